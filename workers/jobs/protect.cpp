#include "jobs/protect.h"

#include "jobs/payload.h"

namespace mm::jobs {

Mesh make_copy(const PreparedAsset& asset, const Key& key, const Nonce& nonce,
               std::uint64_t payload, const WatermarkSettings& settings) {
  Mesh copy = asset.control;
  copy.points = embed(asset.basis, asset.control.points, payload_to_bits(payload, settings.message_bits),
                      key, nonce, settings.params);
  undo(asset.normalization, copy.points);
  return copy;
}

}  // namespace mm::jobs
