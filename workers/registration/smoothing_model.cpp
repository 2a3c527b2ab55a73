#include "registration/smoothing_model.h"

#include <cmath>
#include <cstdio>

#include "attacks/perturb.h"

namespace mm {
namespace {

double rms(const Points& a, const Points& b) {
  return a.rows() == 0 ? 0.0 : std::sqrt((a - b).squaredNorm() / static_cast<double>(a.rows()));
}

// Explaining the suspect twice as well as no smoothing: a copy that was not smoothed differs
// from the original by its mark and noise, and one smoothing step moves a CAD part's features by
// far more, so only a smoothed copy passes.
constexpr double kBetter = 0.5;

}  // namespace

std::string SmoothingModel::describe() const {
  if (iterations == 0) return {};
  char buf[96];
  std::snprintf(buf, sizeof buf, "umbrella smoothing, lambda %g x %d", lambda, iterations);
  return buf;
}

SmoothingModel fit_smoothing(const Mesh& connectivity, const Points& original, const Points& suspect, bool align,
                             int max_iterations) {
  SmoothingModel best;
  if (suspect.rows() != original.rows() || original.rows() != connectivity.num_vertices() || original.rows() < 3)
    return best;
  // The suspect's distance from a candidate, after the similarity onto it when aligning.
  auto distance = [&](const Points& target, Similarity* onto) {
    *onto = align ? fit_similarity(suspect, target) : Similarity{};
    return rms(onto->apply(suspect), target);
  };
  best.unsmoothed_rms = distance(original, &best.to_original);
  best.residual_rms = best.unsmoothed_rms;
  const attacks::UmbrellaSmoother smoother(connectivity);
  double best_rms = kBetter * best.unsmoothed_rms;
  for (double lambda : {0.25, 0.5, 0.75, 1.0}) {
    Points smoothed = original;
    double previous = best.unsmoothed_rms;
    for (int it = 1; it <= max_iterations; ++it) {
      smoother.step(smoothed, lambda);
      Similarity onto;
      const double e = distance(smoothed, &onto);
      if (e < best_rms) {
        best_rms = e;
        best.lambda = lambda;
        best.iterations = it;
        best.residual_rms = e;
        best.smoothed = smoothed;
        best.to_original = onto;
      }
      if (e > previous && it > 1) break;  // past the suspect's amount of smoothing
      previous = e;
    }
  }
  return best;
}

}  // namespace mm
