// The stream's body (docs/stream-format.md): a compact header, then one body coded by the
// adaptive binary range coder (codec/range_coder.h): the face traversal's decisions
// (codec/connectivity.h), coordinate residuals, crease flags per edge, corner flags per vertex
// and metadata, each with small context models. The envelope (magic, version, CRC-32) is
// checked by the caller (codec/stream_detail.h).
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "codec/stream.h"

namespace mm::codec_detail {

// Ideal sizes (bits) of the body's sections, for reports.
struct SectionBits {
  double faces = 0, coordinates = 0, creases = 0, corners = 0, metadata = 0;
  std::size_t header_bytes = 0;  // magic .. counts
};

// Encodes a mesh already validated by encode(); tries each coordinate prediction and keeps the
// smallest stream (ties: the first). With `snap` (per vertex, cells; CodecParams::snap_cells)
// the grid values may move by up to that many cells where another value codes cheaper.
std::vector<std::uint8_t> encode_v3(const Mesh& mesh, const Quantization& q, const GridPoints& grid,
                                    const std::map<std::string, std::string>& metadata,
                                    SectionBits* bits = nullptr, const std::vector<std::uint8_t>* snap = nullptr);

// Decodes a stream whose magic, version (3), size limit and checksum were checked.
DecodedStream decode_v3(const std::uint8_t* data, std::size_t size, const std::string& source);

}  // namespace mm::codec_detail
