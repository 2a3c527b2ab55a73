#include "compression/compress_part.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <new>
#include <optional>

#include "subdivision/subdivide.h"

namespace mm {

double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

const FitAtAngle& PartFits::kept() const {
  const FitAtAngle* best = nullptr;
  for (const auto& f : fits) {
    if (f.result.tolerance_met) return f;
    if (!best || f.result.stats.hausdorff / f.result.stats.diagonal <
                     best->result.stats.hausdorff / best->result.stats.diagonal)
      best = &f;
  }
  return *best;
}

namespace {

// The crease networks of the angles kept so far, computed only when a later angle needs to be
// compared with them (one angle alone never computes its network twice).
class Networks {
 public:
  Networks(const Mesh& part, const CompressOptions& options, const std::string& source)
      : part_(part), options_(options), source_(source) {}

  // The angles of `list` whose networks are new, in order.
  std::vector<double> distinct(const std::vector<double>& list) {
    std::vector<double> fresh;
    for (const double angle : list) {
      if (angles_.empty()) {
        angles_.push_back(angle);
        networks_.emplace_back();
        fresh.push_back(angle);
        continue;
      }
      Features f = features(angle);
      bool seen = false;
      for (std::size_t k = 0; k < angles_.size() && !seen; ++k) {
        if (!networks_[k]) networks_[k] = features(angles_[k]);
        seen = same_crease_network(*networks_[k], f);
      }
      if (seen) continue;
      angles_.push_back(angle);
      networks_.emplace_back(std::move(f));
      fresh.push_back(angle);
    }
    return fresh;
  }

 private:
  Features features(double angle) const {
    CompressOptions o = options_;
    o.angle_degrees = angle;
    return compress_features(part_, o, source_);
  }
  const Mesh& part_;
  const CompressOptions& options_;
  const std::string& source_;
  std::vector<double> angles_;
  std::vector<std::optional<Features>> networks_;
};

}  // namespace

PartFits fit_part(const Mesh& part, const MeasuredSurface& measured, const PartOptions& options,
                  const std::string& source) {
  CompressOptions fit = options.fit;
  if (!fit.verify)
    fit.verify = [&measured, levels = fit.levels, tolerance = fit.tolerance](const Mesh& control) {
      return decoded_within(measured, control, levels, tolerance);
    };
  PartFits out;
  out.fits.reserve(options.angles.size() + options.fallback_angles.size());  // `polyhedra` points into it
  Networks networks(part, fit, source);
  std::optional<InputError> refusal;
  struct Outcome {
    std::optional<CompressResult> result;
    std::shared_ptr<const CompressState> rounds;
    std::exception_ptr error;
    double cpu = 0;
  };
  const auto fit_all = [&](const std::vector<double>& list, int at_once, bool fallback, const Mesh& part) {
    std::vector<Outcome> done(list.size());
    const auto task = [&](int k) {
      const double c0 = thread_cpu_seconds();
      CompressOptions o = fit;
      o.angle_degrees = list[static_cast<std::size_t>(k)];
      Outcome& d = done[static_cast<std::size_t>(k)];
      try {
        // With coarsening, the rounds only: it is spent on one angle below.
        d.result = o.coarsen ? compress_rounds(part, o, source, d.rounds) : compress(part, o, source);
      } catch (...) {
        d.error = std::current_exception();
      }
      d.cpu = thread_cpu_seconds() - c0;
    };
    const int n = std::max(1, std::min(at_once, static_cast<int>(list.size())));
    out.threads = std::max(out.threads, n);
    if (options.parallel && n > 1)
      options.parallel(static_cast<int>(list.size()), n, task);
    else
      for (int k = 0; k < static_cast<int>(list.size()); ++k) task(k);
    for (std::size_t k = 0; k < list.size(); ++k) {
      out.cpu_seconds += done[k].cpu;
      if (done[k].result) {
        out.fits.push_back({list[k], std::move(*done[k].result), std::move(done[k].rounds)});
        continue;
      }
      try {
        std::rethrow_exception(done[k].error);
      } catch (const InputError& e) {
        if (!refusal) refusal = e;
        out.refused.push_back(list[k]);
      } catch (const std::bad_alloc&) {
        throw;
      } catch (const std::exception&) {
        if (!fallback) throw;
        out.refused.push_back(list[k]);  // a better try that failed: the other fits stand
      }
    }
  };
  fit_all(networks.distinct(options.angles), options.at_once, false, part);
  const auto met = [&out] {
    return std::any_of(out.fits.begin(), out.fits.end(),
                       [](const FitAtAngle& f) { return !f.result.candidates.empty(); });
  };
  for (const double angle : options.fallback_angles) {
    if (met()) break;
    fit_all(networks.distinct({angle}), 1, true, part);
  }
  if (out.fits.empty()) {
    if (refusal) throw *refusal;
    throw InputError(source, "no crease angle could be fitted");
  }
  // The closest fit again with `mesh` and no round limit; a better result replaces it (whether
  // one did is returned).
  const auto extend = [&](const Mesh& mesh, int splits) {
    const FitAtAngle& closest = out.kept();
    const double angle = closest.angle, error = closest.result.stats.hausdorff / closest.result.stats.diagonal;
    const std::size_t before = out.fits.size();
    fit.max_rounds = kUnlimitedRounds;
    fit_all({angle}, 1, true, mesh);
    if (out.fits.size() == before) return false;
    FitAtAngle& fresh = out.fits.back();
    fresh.result.part_splits = splits;
    const auto old = std::find_if(out.fits.begin(), out.fits.end() - 1,
                                  [&](const FitAtAngle& f) { return f.angle == angle; });
    if (!fresh.result.tolerance_met && fresh.result.stats.hausdorff / fresh.result.stats.diagonal >= error &&
        splits > 0) {
      out.fits.pop_back();  // a split that came no closer: the unsplit fit stands
      return false;
    }
    if (old != out.fits.end() - 1) out.fits.erase(old);
    return true;
  };
  if (!met() && options.extend) {
    extend(part, 0);
    Mesh split;
    for (int s = 1; s <= options.max_splits && !met(); ++s) {
      const CompressResult& r = out.kept().result;
      if (!r.all_vertices || r.input_vertices >= fit.max_vertices) break;
      try {
        split = subdivide_linear(s == 1 ? part : split, 1);
      } catch (const InputError&) {
        break;  // not a manifold the split takes: the fit so far stands
      }
      if (!extend(split, s)) break;
    }
  }
  if (fit.coarsen) {
    FitAtAngle* pick = nullptr;
    for (auto& f : out.fits)
      if (!f.result.candidates.empty() &&
          (!pick || f.result.control.num_vertices() < pick->result.control.num_vertices()))
        pick = &f;
    if (pick) {
      const double c0 = thread_cpu_seconds();
      pick->result = coarsen_rounds(*pick->rounds);
      pick->coarsened = true;
      out.cpu_seconds += thread_cpu_seconds() - c0;
    }
  }
  for (auto& f : out.fits) f.rounds.reset();  // their trees and samples are no longer needed
  for (const auto& f : out.fits)
    for (const auto& c : f.result.candidates) out.polyhedra.emplace_back(&f, &c.control);
  std::stable_sort(out.polyhedra.begin(), out.polyhedra.end(), [](const auto& x, const auto& y) {
    return x.second->num_vertices() < y.second->num_vertices();
  });
  return out;
}

CompressedPart compress_part(const Mesh& part, const MeasuredSurface& measured, const PartOptions& options,
                             const std::string& source) {
  CompressedPart out;
  out.fits = fit_part(part, measured, options, source);
  const auto t0 = std::chrono::steady_clock::now();
  StreamSearch search = options.stream;
  search.tolerance = options.fit.tolerance;
  search.levels = options.fit.levels;
  search.fit_met = !out.fits.polyhedra.empty();
  std::vector<const Mesh*> polyhedra;
  std::vector<const FitAtAngle*> from;  // the fit each polyhedron came from
  for (const auto& [fit, control] : out.fits.polyhedra) polyhedra.push_back(control), from.push_back(fit);
  if (polyhedra.empty()) {
    // The closest fit: after extend() that is the one fitted on to the budget, which need not be
    // the first angle's.
    const FitAtAngle& closest = out.fits.kept();
    polyhedra.push_back(&closest.result.control);
    from.push_back(&closest);
  }
  out.stream = smallest_stream(measured, polyhedra, search, source);
  out.control = polyhedra[static_cast<std::size_t>(out.stream.polyhedron)];
  out.fit = from[static_cast<std::size_t>(out.stream.polyhedron)];
  out.candidates = static_cast<int>(polyhedra.size());
  out.stream_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace mm
