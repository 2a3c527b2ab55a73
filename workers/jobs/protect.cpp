#include "jobs/protect.h"

#include "codec/stream.h"
#include "jobs/payload.h"
#include "subdivision/decompress.h"

namespace mm::jobs {

Mesh make_copy(const PreparedAsset& asset, const Key& key, const Nonce& nonce,
               std::uint64_t payload, const WatermarkSettings& settings) {
  Mesh copy = asset.control;
  copy.points = embed(asset.basis, asset.control.points, payload_to_bits(payload, settings.message_bits),
                      key, nonce, settings.params);
  undo(asset.normalization, copy.points);
  return copy;
}

CopyFiles make_copy_files(const PreparedAsset& asset, const Mesh& marked_control,
                          const StreamSettings& stream, bool triangles_only) {
  CopyFiles f;
  CodecParams cp;
  cp.quant_bits = stream.quant_bits;
  cp.metadata = stream.metadata;
  f.stream = encode(marked_control, cp);
  DecodedStream d = decode(f.stream, "copy stream");
  f.decoded = asset.levels > 0 ? decompress_to_level(d.mesh, asset.levels) : d.mesh;
  if (triangles_only) f.decoded = triangulate(f.decoded);
  return f;
}

}  // namespace mm::jobs
