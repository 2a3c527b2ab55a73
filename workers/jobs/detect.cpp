#include "jobs/detect.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/SparseCholesky>
#include <unordered_set>

#include "jobs/payload.h"
#include "geometry/nearest_neighbours.h"

namespace mm::jobs {

ResyncContext make_resync_context(const PreparedAsset& asset) {
  // One level beyond the copies': a polyhedron refined once more in its own face order is matched
  // index by index (exact); the surface fit is the fallback for everything else.
  const int max_level = std::clamp(asset.levels + 1, 1, 4);
  return ResyncContext(asset.control, max_level, std::clamp(asset.levels, 1, max_level));
}

Resynchronized resynchronize_suspect(const ResyncContext& context, const Mesh& suspect,
                                     const ResyncOptions& options) {
  Resynchronized r = resynchronize(context, suspect, options);
  // A re-subdivided copy was solved with its own operator; the pass below knows only S_L.
  if (r.method != "subdivided" || !r.order_recovered || r.level < 1 || r.resubdivided) return r;
  const SparseOperator& S = context.subdivision(r.level).S;
  const Points moved = r.to_control_frame.apply(suspect.points);
  const PointTree tree(moved);
  Eigen::SparseMatrix<double> St = S.transpose();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(St * S);
  if (solver.info() != Eigen::Success) return r;
  const double diag = context.diagonal() > 0 ? context.diagonal() : 1.0;
  Points matched(S.rows(), 3);
  std::vector<int> pick(static_cast<std::size_t>(S.rows()));
  auto match = [&](const Points& control) {
    Points predicted = S * control;
    for (Eigen::Index i = 0; i < predicted.rows(); ++i) {
      pick[static_cast<std::size_t>(i)] = tree.nearest(predicted.row(i).transpose());
      matched.row(i) = moved.row(pick[static_cast<std::size_t>(i)]);
    }
    return std::sqrt((predicted - matched).rowwise().squaredNorm().mean()) / diag;
  };
  double residual = match(r.points);
  for (int round = 0; round < 8; ++round) {
    Points x = solver.solve(St * matched);
    if (solver.info() != Eigen::Success || !x.allFinite()) break;
    double next = match(x);
    if (!(next < residual)) break;
    residual = next;
    r.points = std::move(x);
    r.residual_rms = residual;
    std::unordered_set<int> distinct(pick.begin(), pick.end());
    r.matched_fraction = static_cast<double>(distinct.size()) / static_cast<double>(S.rows());
  }
  return r;
}

Finding finding_of(double p, double p_threshold, bool payload_matches) {
  if (p < p_threshold) return Finding::present;
  if (payload_matches) return Finding::inconclusive;
  return Finding::absent;
}

namespace {
std::string three_digits(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", x);
  return buf;
}
}  // namespace

std::string inconclusive_reason(const std::string& what, const std::string& p_name, double p, double p_threshold,
                                bool payload_matches) {
  if (finding_of(p, p_threshold, payload_matches) != Finding::inconclusive) return {};
  return what + "'s payload decoded whole but its mark's " + p_name + " " + three_digits(p) + " is not below " +
         three_digits(p_threshold);
}

MarkP verdict_p(const Extraction& e, const NullCalibration& cal) {
  if (e.neg_log10_p <= cal.neg_log10_p) return {e.p_value, e.neg_log10_p};
  return {cal.p, cal.neg_log10_p};
}

MarkP combined_p(const MarkP& sign, const MatchedScore& matched) {
  const double best = std::max(sign.neg_log10_p, matched.neg_log10_p);
  MarkP out;
  out.neg_log10_p = std::max(0.0, best - std::log10(2.0));
  out.p = std::min(1.0, 2 * std::min(sign.p, matched.p));
  return out;
}

double corrected_p(double p, int copies_tried) {
  return std::min(1.0, p * std::max(1.0, static_cast<double>(copies_tried)));
}

bool better_copy(const CopyScore& a, const CopyScore& b) {
  if (a.corrected_p != b.corrected_p) return a.corrected_p < b.corrected_p;
  return a.correlation > b.correlation;
}

CopyStatistics copy_statistics(const SpectralBasis& basis, const SuspectEvidence& evidence, const Key& key,
                               const Nonce& nonce, const EmbedParams& params, const std::vector<bool>& expected) {
  const int bits = static_cast<int>(expected.size());
  CopyStatistics s;
  s.sign = extract(basis, evidence.spectral, bits, key, nonce, params, &expected);
  s.calibration = calibrate_null(s.sign.signs, bits, s.sign.correlation, &expected, evidence.nulls);
  s.sign_p = verdict_p(s.sign, s.calibration);
  for (std::size_t r = 0; r < evidence.matched.size(); ++r) {
    MatchedScore m = matched_score(evidence.matched[r], key, nonce, expected, usable_coefficients(basis));
    if (r == 0 || m.statistic > s.matched.statistic) {
      s.matched = std::move(m);
      s.reading = static_cast<int>(r);
    }
  }
  if (evidence.matched.size() > 1) {
    const double readings = static_cast<double>(evidence.matched.size());
    s.matched.p = std::min(1.0, s.matched.p * readings);
    s.matched.neg_log10_p = std::max(0.0, s.matched.neg_log10_p - std::log10(readings));
  }
  s.p = combined_p(s.sign_p, s.matched);
  s.message = s.matched.neg_log10_p > s.sign_p.neg_log10_p ? s.matched.message : s.sign.message;
  return s;
}

SuspectReadings suspect_readings(const ResyncContext& context, const Mesh& suspect, const Resynchronized& r) {
  SuspectReadings out;
  if (r.method == "surface-fit") {
    out.surfaces = surface_readings(context, suspect, r.to_control_frame);
    out.control_points = false;
  } else if (r.method == "piece") {
    out.surfaces.push_back(surface_in_frame(context, suspect));
  }
  return out;
}

SuspectEvidence suspect_evidence(const SpectralBasis& basis, const Points& original, const Points& registered,
                                 const SuspectReadings* readings, int message_bits, const EmbedParams& params) {
  SuspectEvidence e;
  e.spectral = spectral_displacement(basis, original, registered);
  for (std::size_t r = 0; readings && r < readings->surfaces.size(); ++r) {
    const SurfaceOffsets& s = readings->surfaces[r];
    if (s.empty()) continue;
    e.matched.push_back(
        surface_evidence(basis, original, s.rows, s.normals, s.offsets, s.nuisance, message_bits, params));
    e.readings.push_back(r < std::size(kSurfaceReadings) ? kSurfaceReadings[r] : "surface " + std::to_string(r));
  }
  if (e.matched.empty() || !readings || readings->control_points) {
    e.matched.push_back(coefficient_evidence(basis, original, registered, message_bits, params));
    e.readings.push_back("control points");
  }
  // The sign count runs over the sequence's r * l entries, as the matched evidence does.
  e.nulls = make_null_sequences(e.matched.front().u.size());
  return e;
}

std::vector<CopyScore> score_copies(const PreparedAsset& asset, const Points& registered,
                                    const std::vector<CopyCandidate>& copies, const SuspectReadings* readings) {
  std::vector<CopyScore> scores;
  // The evidence depends on the suspect and the copies' settings, not on keys.
  SuspectEvidence evidence;
  const WatermarkSettings* evidence_for = nullptr;
  for (const auto& c : copies) {
    if (!evidence_for || evidence_for->message_bits != c.settings.message_bits ||
        evidence_for->params.method != c.settings.params.method ||
        evidence_for->params.strength != c.settings.params.strength ||
        evidence_for->params.threshold != c.settings.params.threshold) {
      evidence = suspect_evidence(asset.basis, asset.control.points, registered, readings, c.settings.message_bits,
                                  c.settings.params);
      evidence_for = &c.settings;
    }
    const std::vector<bool> expected = payload_to_bits(c.payload, c.settings.message_bits);
    const CopyStatistics st = copy_statistics(asset.basis, evidence, c.key, c.nonce, c.settings.params, expected);
    CopyScore s;
    s.copy_id = c.copy_id;
    s.strength = c.settings.params.strength;
    s.correlation = st.sign.correlation;
    s.compared = st.sign.compared;
    s.binomial_p = st.sign.p_value;
    s.binomial_neg_log10_p = st.sign.neg_log10_p;
    s.calibrated_p = st.calibration.p;
    s.calibrated_neg_log10_p = st.calibration.neg_log10_p;
    s.null_mean = st.calibration.mean;
    s.null_sd = st.calibration.sd;
    s.sign_neg_log10_p = st.sign_p.neg_log10_p;
    s.matched_statistic = st.matched.statistic;
    s.matched_neg_log10_p = st.matched.neg_log10_p;
    s.matched_reading = evidence.readings[static_cast<std::size_t>(st.reading)];
    s.p_value = st.p.p;
    s.neg_log10_p = st.p.neg_log10_p;
    s.corrected_p = s.p_value;
    const std::vector<bool>& decoded = st.message;
    s.decoded_payload = bits_to_payload(decoded);
    s.payload_matches = s.decoded_payload == c.payload;
    int wrong = 0;
    for (std::size_t i = 0; i < expected.size() && i < decoded.size(); ++i) wrong += expected[i] != decoded[i];
    s.bit_error_rate = expected.empty() ? 0.0 : static_cast<double>(wrong) / static_cast<double>(expected.size());
    scores.push_back(s);
  }
  return scores;
}

Verdict detect_copy(const PreparedAsset& asset, const Points& registered,
                    const std::vector<CopyCandidate>& copies, double p_threshold) {
  Verdict v;
  v.copies_tried = static_cast<int>(copies.size());
  v.scores = score_copies(asset, registered, copies);
  for (auto& s : v.scores) s.corrected_p = corrected_p(s.p_value, v.copies_tried);
  if (!v.scores.empty()) {
    v.best = *std::min_element(v.scores.begin(), v.scores.end(), better_copy);
    v.attributed = finding_of(v.best.corrected_p, p_threshold, v.best.payload_matches) == Finding::present;
  }
  return v;
}

}  // namespace mm::jobs
