#include "jobs/detect.h"

#include <algorithm>

#include "jobs/payload.h"

namespace mm::jobs {

ResyncContext make_resync_context(const PreparedAsset& asset) {
  // One level beyond the copies': a polyhedron refined once more in its own face order is matched
  // index by index (exact); the surface fit is the fallback for everything else.
  const int max_level = std::clamp(asset.levels + 1, 1, 4);
  return ResyncContext(asset.control, max_level, std::clamp(asset.levels, 1, max_level));
}

Verdict detect_copy(const PreparedAsset& asset, const Points& registered,
                    const std::vector<CopyCandidate>& copies, double p_threshold) {
  Verdict v;
  v.copies_tried = static_cast<int>(copies.size());
  const double tried = std::max<double>(1.0, static_cast<double>(copies.size()));
  for (const auto& c : copies) {
    Extraction e = extract(asset.basis, asset.control.points, registered, c.settings.message_bits,
                           c.key, c.nonce, c.settings.params);
    CopyScore s;
    s.copy_id = c.copy_id;
    s.correlation = e.correlation;
    s.p_value = e.p_value;
    s.neg_log10_p = e.neg_log10_p;
    s.corrected_p = std::min(1.0, e.p_value * tried);
    s.decoded_payload = bits_to_payload(e.message);
    s.payload_matches = s.decoded_payload == c.payload;
    std::vector<bool> expected = payload_to_bits(c.payload, c.settings.message_bits);
    int wrong = 0;
    for (std::size_t i = 0; i < expected.size() && i < e.message.size(); ++i) wrong += expected[i] != e.message[i];
    s.bit_error_rate = expected.empty() ? 0.0 : static_cast<double>(wrong) / static_cast<double>(expected.size());
    v.scores.push_back(s);
  }
  if (!v.scores.empty()) {
    v.best = *std::min_element(v.scores.begin(), v.scores.end(), [](const CopyScore& a, const CopyScore& b) {
      if (a.corrected_p != b.corrected_p) return a.corrected_p < b.corrected_p;
      return a.correlation > b.correlation;
    });
    v.attributed = v.best.corrected_p < p_threshold && v.best.payload_matches;
  }
  return v;
}

}  // namespace mm::jobs
