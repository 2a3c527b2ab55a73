// Detect: which issued copy (if any) a registered suspect carries.
//
// Every copy of the asset is tried with its own key and nonce. The verdict names a copy only if
// its p-value, Bonferroni-corrected for the number of copies tried, is below the threshold AND
// the message decoded with that copy's key equals that copy's payload. An unmarked or foreign
// mesh has no reason to pass either test, so it is never attributed.
//
// Each copy gets two statistics. The sign count's p-value is the larger of two: the exact tail
// of extract() (the binomial model: chance signs independent and fair) and an empirically
// calibrated one (calibrate_null(): the same statistic against kNullSequences public sequences
// unrelated to any copy). The matched score (watermark/matched_score.h) weighs each coefficient
// by how far it moved against what the attack and the noise explain, with Hoeffding's
// distribution-free bound. The copy's p-value is the smaller of the two, doubled (Bonferroni over
// the two statistics). All of them are kept, so the evidence states which one bound.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "jobs/protect.h"
#include "registration/resynchronize.h"
#include "registration/surface_offsets.h"
#include "watermark/matched_score.h"
#include "watermark/null_calibration.h"
#include "watermark/surface_evidence.h"

namespace mm::jobs {

struct CopyCandidate {
  std::int64_t copy_id = 0;
  Key key{};  // the copy's customer key version; never logged
  Nonce nonce{};
  std::uint64_t payload = 0;
  WatermarkSettings settings;
};

struct CopyScore {
  std::int64_t copy_id = 0;
  double correlation = 0;
  int compared = 0;      // coefficient signs compared (m)
  double p_value = 1;    // raw: combined_p of the sign count's and the matched score's
  double corrected_p = 1;  // min(1, p * copies tried)
  double neg_log10_p = 0;  // -log10 of the raw p-value, meaningful where p underflows to 0
  double binomial_p = 1, binomial_neg_log10_p = 0;      // extract()'s exact tail
  double calibrated_p = 1, calibrated_neg_log10_p = 0;  // the empirical-null normal tail
  double null_mean = 0, null_sd = 0;  // of the correlation over the null sequences
  double sign_neg_log10_p = 0;        // the sign count's: the smaller of the two above
  double matched_statistic = 0, matched_neg_log10_p = 0;  // matched_score()
  std::string matched_reading;  // the reading it came from (kSurfaceReadings, "control points")
  std::uint64_t decoded_payload = 0;
  bool payload_matches = false;
  double bit_error_rate = 0;
  double strength = 0;  // the mark's strength a this copy was issued with, which the scores assumed
};

struct Verdict {
  bool attributed = false;
  int copies_tried = 0;
  CopyScore best;  // smallest corrected p (meaningful when copies_tried > 0)
  std::vector<CopyScore> scores;  // one per candidate, in input order
};

// The resynchronisation context for suspects of this asset: its normalised control polyhedron,
// recognising subdivision up to one level beyond the decoded copies' (a leaker may refine once
// more); remeshed suspects are fitted against the surface at the copies' level.
ResyncContext make_resync_context(const PreparedAsset& asset);

// resynchronize(), then, when the suspect is a refined copy whose vertex order was lost (an STL
// file, a re-export) and had to be recovered by nearest neighbours against the unmarked surface,
// refines that: each refined vertex of the polyhedron just recovered takes its nearest suspect
// vertex, and the control points are solved again by least squares, while the residual drops
// (at most 8 rounds). The mark moves refined vertices by a fair fraction of their spacing, so
// matching against the unmarked surface pairs about 1 % of them wrongly; against the recovered
// (marked) surface almost none.
Resynchronized resynchronize_suspect(const ResyncContext& context, const Mesh& suspect,
                                     const ResyncOptions& options = {});

// What a copy's score says: the one rule behind every verdict (detect_copy's `attributed`, the
// daemon's detect jobs, `meshmark extract`). Present: its mark matches, p below the threshold.
// The p-values are exact under the null (the copy's key stream is fair and independent of a
// suspect made without it), so the mark alone is the evidence; the payload is decoded and its
// wrong bits reported beside it (an attack damages some bits long before the mark fades).
// Inconclusive: the payload decodes whole while p is not below the threshold, which names no
// customer and does not say "no watermark" either. Absent: neither.
enum class Finding { present, inconclusive, absent };
Finding finding_of(double p, double p_threshold, bool payload_matches);
// Why a finding is inconclusive, for a report: "copy 4's payload decoded whole but its mark's
// corrected p 3.55e-15 is not below 1e-300" (`what` "copy 4", `p_name` "corrected p"). Empty for
// the other findings.
std::string inconclusive_reason(const std::string& what, const std::string& p_name, double p, double p_threshold,
                                bool payload_matches);

// A mark's p-value for the verdict: the more conservative of extract()'s exact tail and the
// empirical-null tail, compared in -log10 (which survives underflow).
struct MarkP {
  double p = 1;
  double neg_log10_p = 0;
};
MarkP verdict_p(const Extraction& extraction, const NullCalibration& calibration);
// The copy's p from both statistics: 2 min(sign p, matched p), in -log10 too.
MarkP combined_p(const MarkP& sign, const MatchedScore& matched);

// One copy's two statistics against a registered suspect and what the verdict takes from them:
// the sign count against the copy's whole sequence (`expected`, its issued payload, fixes it)
// with its calibrated null, the matched score over `evidence`, their combined p, and the message
// as the stronger statistic decodes it. The one scoring behind detect jobs and `meshmark extract`.
struct CopyStatistics {
  Extraction sign;
  NullCalibration calibration;
  MarkP sign_p;
  // The largest of the readings' matched scores, its p multiplied by their count (Bonferroni).
  MatchedScore matched;
  int reading = 0;  // which of SuspectEvidence::matched it is
  MarkP p;                    // combined_p(sign_p, matched)
  std::vector<bool> message;  // decoded by the stronger statistic
};
// What the matched score reads of a suspect resynchronised as `r`, the one rule of detect jobs and
// `meshmark extract`: a "surface-fit" suspect, surface_readings(); a "piece", its surface in the
// asset's frame besides its control points (a simplification may thin a piece's vertices out
// until its control points are poorly determined while its surface still carries the mark);
// anything else, its control points.
struct SuspectReadings {
  std::vector<SurfaceOffsets> surfaces;
  bool control_points = true;
};
SuspectReadings suspect_readings(const ResyncContext& context, const Mesh& suspect, const Resynchronized& r);

// What scoring takes from a suspect that no copy's key changes, made once for all the copies of
// a polyhedron with the same settings: the sign count's spectral displacement, the calibration's
// null sequences, and the matched score's evidence, one per reading: on the suspect's surface
// (watermark/surface_evidence.h) for each of `readings`' non-empty surfaces, and from the
// registered control points (coefficient_evidence) when it asks for them or has no surface
// (`readings` null: the control points alone).
struct SuspectEvidence {
  SpectralDisplacement spectral;
  NullSequences nulls;
  std::vector<CoefficientEvidence> matched;  // one per reading, at least one
  std::vector<std::string> readings;         // their names (kSurfaceReadings, "control points")
};
SuspectEvidence suspect_evidence(const SpectralBasis& basis, const Points& original, const Points& registered,
                                 const SuspectReadings* readings, int message_bits, const EmbedParams& params);

CopyStatistics copy_statistics(const SpectralBasis& basis, const SuspectEvidence& evidence, const Key& key,
                               const Nonce& nonce, const EmbedParams& params, const std::vector<bool>& expected);

// Each copy's score of a suspect resynchronised to asset.control (resynchronize(...).points),
// uncorrected (corrected_p = p_value), in input order.
std::vector<CopyScore> score_copies(const PreparedAsset& asset, const Points& registered,
                                    const std::vector<CopyCandidate>& copies,
                                    const SuspectReadings* readings = nullptr);
// Bonferroni: min(1, p x copies tried).
double corrected_p(double p, int copies_tried);
// The better of two scores for the verdict: the smaller corrected p, then the larger correlation.
bool better_copy(const CopyScore& a, const CopyScore& b);

// One polyhedron's copies alone: score_copies, corrected for copies.size(), the best by
// better_copy and its finding. detect_suspect() applies the same rule over every candidate.
Verdict detect_copy(const PreparedAsset& asset, const Points& registered,
                    const std::vector<CopyCandidate>& copies, double p_threshold);

}  // namespace mm::jobs
