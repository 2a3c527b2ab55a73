// Protect: one customer's watermarked copy of a prepared asset.
#pragma once
#include <cstdint>

#include "jobs/prepared_asset.h"
#include "watermark/watermark.h"

namespace mm::jobs {

struct WatermarkSettings {
  EmbedParams params;
  int message_bits = 32;  // payload width; 8..64
};

// Embeds payload_to_bits(payload) with the customer's key and the copy's nonce into the control
// polyhedron and returns the copy in the part's own units (same vertex order and faces as
// asset.control). Pure: no I/O; the caller writes and records it.
Mesh make_copy(const PreparedAsset& asset, const Key& key, const Nonce& nonce,
               std::uint64_t payload, const WatermarkSettings& settings);

}  // namespace mm::jobs
