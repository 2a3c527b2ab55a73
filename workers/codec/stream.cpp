#include "codec/stream.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <system_error>

#include "codec/bytes.h"
#include "codec/connectivity.h"
#include "codec/prediction.h"
#include "codec/rice.h"
#include "codec/stream_detail.h"
#include "codec/stream_v3.h"
#include "support/atomic_file.h"

namespace mm {
namespace {

using codec_detail::Header;
using codec_detail::Reader;
using codec_detail::Writer;
using codec_detail::unzigzag;
using codec_detail::zigzag;

std::size_t bitset_bytes(std::size_t bits) { return (bits + 7) / 8; }

// Reads a bitset of `bits` bits whose padding bits must be zero.
std::vector<bool> read_bitset(Reader& in, std::size_t bits, const char* what) {
  const std::uint8_t* b = in.bytes(bitset_bytes(bits), what);
  std::vector<bool> out(bits);
  for (std::size_t i = 0; i < bits; ++i) out[i] = (b[i / 8] >> (i % 8)) & 1;
  if (bits % 8 && (b[bits / 8] >> (bits % 8)) != 0) in.fail(std::string("padding bits set in ") + what);
  return out;
}

void write_bitset(Writer& out, const std::vector<bool>& bits) {
  std::vector<std::uint8_t> b(bitset_bytes(bits.size()), 0);
  for (std::size_t i = 0; i < bits.size(); ++i)
    if (bits[i]) b[i / 8] |= static_cast<std::uint8_t>(1u << (i % 8));
  out.raw(b.data(), b.size());
}

using codec_detail::kMaxKeyBytes;
using codec_detail::kMaxMetadataEntries;
using codec_detail::kMaxValueBytes;
using codec_detail::valid_key;

// Most bits one Rice-coded coordinate can take: the quotient cap, its stop bit, k low bits.
constexpr std::size_t kMaxCoordBits = codec_detail::kMaxRiceQuotient + 1 + codec_detail::kMaxRiceParameter;
constexpr std::size_t kMaxIndexVarint = 5;

// Payload size bounds implied by the counts: every element takes at least its minimum encoding
// and at most its maximum one. A face costs at least a symbol and a vertex byte, at most a
// start symbol, three gate symbols and four 5-byte indices or ranks.
std::pair<std::uint64_t, std::uint64_t> payload_bounds(const Header& h) {
  const std::uint64_t v = h.vertices, f = h.faces, c = h.corners, m = h.metadata_entries;
  const std::uint64_t lo = 3 + 2 * f + 3 + 1 + bitset_bytes(3 * v) + c + 3 * m;
  const std::uint64_t hi = 3 * kMaxIndexVarint + f * (4 + 4 * 2 * kMaxIndexVarint) +
                           bitset_bytes(4 * f) + 3 + kMaxIndexVarint + bitset_bytes(3 * v * kMaxCoordBits) +
                           c * kMaxIndexVarint +
                           m * (2 * 2 + kMaxKeyBytes + kMaxValueBytes);
  return {lo, hi};
}

// ---------------------------------------------------------------------------------------------
// Encoder

void validate_for_encoding(const Mesh& mesh, const CodecParams& params) {
  const std::string src = "encode";
  if (params.format_version != 2 && params.format_version != 3)
    throw InputError(src, "format version " + std::to_string(params.format_version) + " cannot be written (2 or 3)");
  const int lowest = params.format_version == 2 ? kMinQuantBitsV3 : kMinQuantBits;
  if (params.quant_bits < lowest || params.quant_bits > kMaxQuantBits)
    throw InputError(src, "quantisation bits " + std::to_string(params.quant_bits) + " outside [" +
                              std::to_string(lowest) + ", " + std::to_string(kMaxQuantBits) +
                              "] for format version " + std::to_string(params.format_version));
  if (static_cast<std::uint64_t>(mesh.num_vertices()) > kMaxStreamVertices)
    throw InputError(src, "too many vertices for a stream");
  if (mesh.faces.size() > kMaxStreamFaces) throw InputError(src, "too many faces for a stream");
  const int n = mesh.num_vertices();
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    if (face.size() != 3 && face.size() != 4)
      throw InputError(src, "face " + std::to_string(f) + " has " + std::to_string(face.size()) +
                                " vertices; streams hold triangles and quads only");
    for (std::size_t k = 0; k < face.size(); ++k) {
      if (face[k] < 0 || face[k] >= n)
        throw InputError(src, "face " + std::to_string(f) + " has vertex index out of range");
      for (std::size_t j = 0; j < k; ++j)
        if (face[j] == face[k])
          throw InputError(src, "face " + std::to_string(f) + " repeats a vertex");
    }
  }
  for (int c : mesh.corners)
    if (c < 0 || c >= n) throw InputError(src, "corner index out of range");
  if (!params.snap_cells.empty()) {
    if (params.format_version != 3)
      throw InputError(src, "snapping (snap_cells) needs format version 3");
    if (params.snap_cells.size() != 3 * static_cast<std::size_t>(n))
      throw InputError(src, "snap_cells has " + std::to_string(params.snap_cells.size()) + " entries for " +
                                std::to_string(n) + " vertices (3 per vertex)");
  }
  if (params.metadata.size() > kMaxMetadataEntries) throw InputError(src, "too many metadata entries");
  for (const auto& [k, v] : params.metadata) {
    if (!valid_key(k)) throw InputError(src, "metadata key is empty, too long or has characters other than [A-Za-z0-9_.-]");
    if (v.size() > kMaxValueBytes) throw InputError(src, "metadata value for '" + k + "' is too long");
  }
}

// The payload, with coordinates coded against the given prediction.
std::vector<std::uint8_t> build_payload(const codec_detail::ConnectivityStreams& streams,
                                        const GridPoints& grid,
                                        const std::vector<bool>& crease_bits,
                                        const std::vector<int>& corners,
                                        const std::map<std::string, std::string>& metadata,
                                        codec_detail::Prediction mode,
                                        const codec_detail::PredictionContext& ctx) {
  Writer w;
  for (const auto* part : {&streams.symbols, &streams.ranks, &streams.vertices}) w.varint(part->size());
  for (const auto* part : {&streams.symbols, &streams.ranks, &streams.vertices})
    w.raw(part->data(), part->size());
  write_bitset(w, crease_bits);
  int prev_corner = -1;
  for (int c : corners) {
    w.varint(static_cast<std::uint64_t>(c - prev_corner - 1));
    prev_corner = c;
  }
  // Residuals (zigzagged unless plain), Rice coded with one parameter per axis, one axis after
  // another: three parameter bytes, the bit stream's byte length, the bit stream.
  std::vector<std::uint64_t> values[3];
  for (int a = 0; a < 3; ++a)
    for (Eigen::Index i = 0; i < grid.rows(); ++i) {
      const std::int64_t r = grid(i, a) - codec_detail::predict(grid, static_cast<int>(i), a, mode, ctx);
      values[a].push_back(mode == codec_detail::Prediction::plain ? static_cast<std::uint64_t>(r) : zigzag(r));
    }
  codec_detail::BitWriter bits;
  for (int a = 0; a < 3; ++a) {
    const int k = codec_detail::best_rice_parameter(values[a]);
    w.u8(static_cast<std::uint8_t>(k));
    for (std::uint64_t u : values[a]) bits.rice(u, k);
  }
  w.varint(bits.bytes().size());
  w.raw(bits.bytes().data(), bits.bytes().size());
  for (const auto& [k, v] : metadata) {
    w.varint(k.size());
    w.raw(k.data(), k.size());
    w.varint(v.size());
    w.raw(v.data(), v.size());
  }
  return std::move(w.bytes);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Outer layer

namespace codec_detail {

std::uint32_t checksum(const std::uint8_t* data, std::size_t size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  while (size > 0) {
    const uInt chunk = static_cast<uInt>(std::min<std::size_t>(size, 1u << 30));
    crc = crc32(crc, data, chunk);
    data += chunk;
    size -= chunk;
  }
  return static_cast<std::uint32_t>(crc);
}

std::vector<std::uint8_t> join(Header h, const std::vector<std::uint8_t>& raw, int zstd_level) {
  std::vector<std::uint8_t> payload;
  h.raw_size = raw.size();
  if (zstd_level > 0) {
    h.flags |= kFlagZstd;
    payload.resize(ZSTD_compressBound(raw.size()));
    const std::size_t n = ZSTD_compress(payload.data(), payload.size(), raw.data(), raw.size(),
                                        std::min(zstd_level, ZSTD_maxCLevel()));
    if (ZSTD_isError(n)) throw InputError("encode", std::string("zstd: ") + ZSTD_getErrorName(n));
    payload.resize(n);
  } else {
    h.flags &= static_cast<std::uint8_t>(~kFlagZstd);
    payload = raw;
  }
  Writer w;
  w.raw(kMagic, 4);
  w.u8(h.version);
  w.u8(h.flags);
  w.u8(h.bits);
  for (int a = 0; a < 3; ++a) w.f64(h.offset[a]);
  w.f64(h.step);
  w.varint(h.vertices);
  w.varint(h.faces);
  w.varint(h.creases);
  w.varint(h.corners);
  w.varint(h.metadata_entries);
  w.varint(h.raw_size);
  w.raw(payload.data(), payload.size());
  const std::uint32_t crc = checksum(w.bytes.data(), w.bytes.size());
  for (int i = 0; i < 4; ++i) w.u8(static_cast<std::uint8_t>(crc >> (8 * i)));
  return std::move(w.bytes);
}

void check_envelope(const std::uint8_t* data, std::size_t size, const std::string& source) {
  if (size >= 4 && std::memcmp(data, kMagic, 4) != 0)
    throw InputError(source, "not a meshmark stream (bad magic)");
  const std::size_t min_size = std::min(kMinBytesV3, kFixedHeaderBytes + 6 + kChecksumBytes);
  if (size < min_size)
    throw InputError(source, "truncated: " + std::to_string(size) + " bytes, a stream has at least " +
                                 std::to_string(min_size));
  if (size > kMaxStreamBytes) throw InputError(source, "stream larger than the 256 MiB limit");
  if (data[4] < kOldestVersion || data[4] > kVersion)
    throw InputError(source, "unsupported format version " + std::to_string(data[4]) +
                                 " (this build reads versions " + std::to_string(kOldestVersion) +
                                 " to " + std::to_string(kVersion) + ")");
  const std::size_t v12_min = kFixedHeaderBytes + 6 + kChecksumBytes;
  if (data[4] < 3 && size < v12_min)
    throw InputError(source, "truncated: " + std::to_string(size) + " bytes, a version " +
                                 std::to_string(data[4]) + " stream has at least " + std::to_string(v12_min));
  const std::size_t body = size - kChecksumBytes;
  std::uint32_t stored = 0;
  for (int i = 0; i < 4; ++i) stored |= static_cast<std::uint32_t>(data[body + i]) << (8 * i);
  if (checksum(data, body) != stored)
    throw InputError(source, "checksum mismatch: the stream is corrupted or truncated");
}

Parts split(const std::uint8_t* data, std::size_t size, const std::string& source) {
  check_envelope(data, size, source);
  if (data[4] > 2) throw InputError(source, "split() reads versions 1 and 2 only");
  const std::size_t body = size - kChecksumBytes;

  Parts parts;
  Header& h = parts.header;
  Reader in(data + 4, body - 4, source, "header");
  h.version = in.u8("version");
  h.flags = in.u8("flags");
  h.bits = in.u8("quantisation bits");
  if (h.flags & ~kKnownFlags) in.fail("unknown flags " + std::to_string(h.flags));
  if (h.bits < kMinQuantBitsV3 || h.bits > kMaxQuantBits)
    in.fail("quantisation bits " + std::to_string(h.bits) + " outside [" +
            std::to_string(kMinQuantBitsV3) + ", " + std::to_string(kMaxQuantBits) + "]");
  for (int a = 0; a < 3; ++a) h.offset[a] = in.f64("offset");
  h.step = in.f64("step");
  if (!h.offset.allFinite() || !std::isfinite(h.step) || !(h.step > 0))
    in.fail("transform is not finite or its step is not positive");
  // Every grid point must map to a finite position.
  const double span = h.step * static_cast<double>((1u << h.bits) - 1u);
  if (!std::isfinite(span) || !(h.offset.array() + span).allFinite())
    in.fail("transform maps the grid beyond the finite range");
  h.vertices = static_cast<std::uint32_t>(in.varint("vertex count", kMaxStreamVertices));
  h.faces = static_cast<std::uint32_t>(in.varint("face count", kMaxStreamFaces));
  h.creases = static_cast<std::uint32_t>(in.varint("crease count", 4ull * h.faces));
  h.corners = static_cast<std::uint32_t>(in.varint("corner count", h.vertices));
  h.metadata_entries = static_cast<std::uint32_t>(in.varint("metadata entry count", kMaxMetadataEntries));
  h.raw_size = in.varint("payload size", kMaxStreamBytes);
  const auto [lo, hi] = payload_bounds(h);
  if (h.raw_size < lo || h.raw_size > hi)
    in.fail("payload size " + std::to_string(h.raw_size) + " inconsistent with the counts (expected " +
            std::to_string(lo) + ".." + std::to_string(hi) + " bytes)");

  const std::uint8_t* payload = in.position();
  const std::size_t payload_size = in.remaining();
  if (h.flags & kFlagZstd) {
    const unsigned long long content = ZSTD_getFrameContentSize(payload, payload_size);
    if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN)
      in.fail("payload is not a zstd frame with a declared size");
    if (content != h.raw_size)
      in.fail("zstd frame size " + std::to_string(content) + " differs from the declared payload size");
    const std::size_t frame = ZSTD_findFrameCompressedSize(payload, payload_size);
    if (ZSTD_isError(frame) || frame != payload_size)
      in.fail("zstd frame does not fill the payload exactly");
    if (h.raw_size > std::max<std::size_t>(kExpansionFloor, kMaxExpansion * payload_size))
      in.fail("zstd frame expands beyond the allowed ratio");
    parts.raw.resize(h.raw_size);
    const std::size_t n = ZSTD_decompress(parts.raw.data(), parts.raw.size(), payload, payload_size);
    if (ZSTD_isError(n)) in.fail(std::string("zstd: ") + ZSTD_getErrorName(n));
    if (n != h.raw_size) in.fail("zstd frame decompressed to the wrong size");
  } else {
    if (payload_size != h.raw_size)
      in.fail("stored payload is " + std::to_string(payload_size) + " bytes, header says " +
              std::to_string(h.raw_size));
    parts.raw.assign(payload, payload + payload_size);
  }
  return parts;
}

}  // namespace codec_detail

// ---------------------------------------------------------------------------------------------

std::vector<std::uint8_t> encode(const Mesh& mesh, const CodecParams& params) {
  validate_for_encoding(mesh, params);
  Quantization q;
  try {
    q = params.format_version >= 3 ? quantization_for(mesh.points, params.quant_bits)
                                   : box_quantization_for(mesh.points, params.quant_bits);
  } catch (const InputError& e) {
    throw InputError("encode", e.reason());
  }
  const GridPoints grid = quantize(mesh.points, q);

  const auto edges = unique_edges(mesh);
  std::vector<bool> crease_bits(edges.size());
  for (auto [a, b] : mesh.creases) {
    if (a > b) std::swap(a, b);
    const auto it = std::lower_bound(edges.begin(), edges.end(), std::make_pair(a, b));
    if (it == edges.end() || *it != std::make_pair(a, b))
      throw InputError("encode", "crease (" + std::to_string(a) + ", " + std::to_string(b) +
                                     ") is not an edge of the mesh");
    crease_bits[it - edges.begin()] = true;
  }
  if (params.format_version == 3)
    return codec_detail::encode_v3(mesh, q, grid, params.metadata, nullptr,
                                   params.snap_cells.empty() ? nullptr : &params.snap_cells);
  std::vector<int> corners = mesh.corners;
  std::sort(corners.begin(), corners.end());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());

  Header h;
  h.version = 2;
  h.bits = static_cast<std::uint8_t>(q.bits);
  h.offset = q.offset;
  h.step = q.step;
  h.vertices = static_cast<std::uint32_t>(mesh.num_vertices());
  h.faces = static_cast<std::uint32_t>(mesh.faces.size());
  h.creases = static_cast<std::uint32_t>(std::count(crease_bits.begin(), crease_bits.end(), true));
  h.corners = static_cast<std::uint32_t>(corners.size());
  h.metadata_entries = static_cast<std::uint32_t>(params.metadata.size());

  // Smallest of the coordinate predictions, compressed or stored. Ties go to the first tried.
  std::vector<std::vector<int>> traversal;
  const auto streams = codec_detail::encode_faces(mesh.faces, mesh.num_vertices(), &traversal, 2);
  codec_detail::PredictionContext ctx;
  ctx.lower = codec_detail::lower_neighbours(edges, mesh.num_vertices());
  ctx.parallelogram = codec_detail::parallelograms(traversal, mesh.num_vertices());
  ctx.max_value = q.max_value();
  std::vector<std::uint8_t> best;
  for (auto mode : {codec_detail::Prediction::parallelogram, codec_detail::Prediction::neighbours,
                    codec_detail::Prediction::previous, codec_detail::Prediction::plain}) {
    Header hd = h;
    hd.flags = static_cast<std::uint8_t>(static_cast<int>(mode) << codec_detail::kPredictionShift);
    const auto raw = build_payload(streams, grid, crease_bits, corners, params.metadata, mode, ctx);
    for (int level : {params.zstd_level, 0}) {
      auto s = codec_detail::join(hd, raw, level);
      // Conservative payload size: header varints take at most 60 bytes, the CRC 4.
      constexpr std::size_t kHeaderMax = codec_detail::kFixedHeaderBytes + 64;
      const bool refused = level > 0 && raw.size() > std::max<std::size_t>(codec_detail::kExpansionFloor,
                                                                           codec_detail::kMaxExpansion * (s.size() > kHeaderMax ? s.size() - kHeaderMax : 0));
      if (!refused && (best.empty() || s.size() < best.size())) best = std::move(s);
    }
  }
  return best;
}

DecodedStream decode(const std::uint8_t* data, std::size_t size, const std::string& source) {
  codec_detail::check_envelope(data, size, source);
  if (data[4] >= 3) return codec_detail::decode_v3(data, size, source);
  codec_detail::Parts parts = codec_detail::split(data, size, source);
  const Header& h = parts.header;
  Reader in(parts.raw.data(), parts.raw.size(), source, "payload");
  const int n = static_cast<int>(h.vertices);

  DecodedStream out;
  out.version = h.version;
  Mesh& mesh = out.mesh;
  std::size_t sizes[3];
  const char* names[3] = {"face symbol bytes", "face rank bytes", "face index bytes"};
  for (int k = 0; k < 3; ++k) sizes[k] = in.varint(names[k], parts.raw.size());
  const std::uint8_t* starts[3];
  for (int k = 0; k < 3; ++k) starts[k] = in.bytes(sizes[k], names[k]);
  mesh.faces = codec_detail::decode_faces(starts[0], sizes[0], starts[1], sizes[1], starts[2],
                                          sizes[2], h.faces, n, h.version, source);

  const auto edges = unique_edges(mesh);
  const std::vector<bool> crease_bits = read_bitset(in, edges.size(), "crease flags");
  for (std::size_t e = 0; e < edges.size(); ++e)
    if (crease_bits[e]) mesh.creases.push_back(edges[e]);
  if (mesh.creases.size() != h.creases)
    in.fail("crease flags mark " + std::to_string(mesh.creases.size()) + " edges, header says " +
            std::to_string(h.creases));

  std::int64_t corner = -1;
  for (std::uint32_t c = 0; c < h.corners; ++c) {
    corner += 1 + static_cast<std::int64_t>(in.varint("corner gap", 0xFFFFFFFFull));
    if (corner >= n) in.fail("corner index " + std::to_string(corner) + " out of range");
    mesh.corners.push_back(static_cast<int>(corner));
  }

  Quantization& q = out.quantization;
  q.bits = h.bits;
  q.offset = h.offset;
  q.step = h.step;
  const int mode_bits = (h.flags & codec_detail::kPredictionMask) >> codec_detail::kPredictionShift;
  if (mode_bits > (h.version >= 2 ? 3 : 2))
    in.fail("unknown coordinate prediction " + std::to_string(mode_bits) + " for format version " +
            std::to_string(h.version));
  const auto mode = static_cast<codec_detail::Prediction>(mode_bits);
  codec_detail::PredictionContext ctx;
  ctx.lower = codec_detail::lower_neighbours(edges, n);
  if (mode == codec_detail::Prediction::parallelogram) ctx.parallelogram = codec_detail::parallelograms(mesh.faces, n);
  ctx.max_value = q.max_value();
  const bool plain = mode == codec_detail::Prediction::plain;
  int rice_k[3];
  for (int& k : rice_k) {
    k = in.u8("Rice parameter");
    if (k > codec_detail::kMaxRiceParameter) in.fail("Rice parameter " + std::to_string(k) + " too large");
  }
  const std::size_t bit_bytes = in.varint("coordinate bit stream length", parts.raw.size());
  const std::uint8_t* bit_data = in.bytes(bit_bytes, "coordinate bit stream");
  Reader bit_errors(bit_data, bit_bytes, source, "coordinates");
  codec_detail::BitReader bits(bit_data, bit_bytes, bit_errors);
  out.grid.resize(n, 3);
  for (int a = 0; a < 3; ++a)
    for (int i = 0; i < n; ++i) {
      const std::uint64_t u = bits.rice(rice_k[a], "coordinate");
      if (u > 2ull * q.max_value())
        bit_errors.fail("vertex " + std::to_string(i) + " residual " + std::to_string(u) + " exceeds the grid");
      const std::int64_t v = plain ? static_cast<std::int64_t>(u)
                                   : codec_detail::predict(out.grid, i, a, mode, ctx) + unzigzag(u);
      if (v < 0 || v > q.max_value())
        bit_errors.fail("vertex " + std::to_string(i) + " coordinate outside the " +
                        std::to_string(q.bits) + "-bit grid");
      out.grid(i, a) = static_cast<std::int32_t>(v);
    }
  bits.expect_end("the coordinate bit stream");
  mesh.points = dequantize(out.grid, q);

  std::string prev_key;
  for (std::uint32_t m = 0; m < h.metadata_entries; ++m) {
    const std::size_t klen = in.varint("metadata key length", kMaxKeyBytes);
    std::string key(reinterpret_cast<const char*>(in.bytes(klen, "metadata key")), klen);
    const std::size_t vlen = in.varint("metadata value length", kMaxValueBytes);
    std::string value(reinterpret_cast<const char*>(in.bytes(vlen, "metadata value")), vlen);
    if (!valid_key(key)) in.fail("invalid metadata key");
    if (m > 0 && !(prev_key < key)) in.fail("metadata keys not strictly increasing");
    prev_key = key;
    out.metadata.emplace(std::move(key), std::move(value));
  }
  if (in.remaining() != 0) in.fail(std::to_string(in.remaining()) + " unexpected trailing bytes");
  return out;
}

// ---------------------------------------------------------------------------------------------
// Files

void write_stream_file(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  try {
    support::write_file_atomic(path, bytes);
  } catch (const std::system_error& e) {
    throw InputError(path, std::string("writing the stream failed: ") + e.what());
  }
}

std::vector<std::uint8_t> read_stream_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(path, "no such file");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(path, "cannot read the file size");
  if (size > kMaxStreamBytes) throw InputError(path, "file larger than the 256 MiB stream limit");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, "cannot open");
  std::vector<std::uint8_t> bytes(size);
  f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(f.gcount()) != size) throw InputError(path, "short read");
  return bytes;
}

DecodedStream decode_file(const std::string& path) { return decode(read_stream_file(path), path); }

std::vector<int> traversal_vertex_order(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  for (const auto& f : mesh.faces)
    for (int v : f)
      if (v < 0 || v >= n) throw std::invalid_argument("traversal_vertex_order: face index out of range");
  std::vector<std::vector<int>> traversal;
  codec_detail::encode_faces(mesh.faces, n, &traversal, 2);  // version 3 runs the same traversal
  std::vector<int> order;
  order.reserve(static_cast<std::size_t>(n));
  std::vector<char> taken(static_cast<std::size_t>(n), 0);
  for (const auto& f : traversal)
    for (int v : f)
      if (!taken[v]) taken[v] = 1, order.push_back(v);
  for (int v = 0; v < n; ++v)
    if (!taken[v]) order.push_back(v);
  return order;
}

Mesh in_traversal_order(const Mesh& mesh, int first) {
  const int n = mesh.num_vertices();
  if (first < 0 || first >= n) throw std::invalid_argument("in_traversal_order: start vertex out of range");
  // Swap `first` and 0, then number by the traversal.
  const auto swapped = [first](int v) { return v == first ? 0 : v == 0 ? first : v; };
  Mesh start = mesh;
  for (auto& f : start.faces)
    for (int& v : f) v = swapped(v);
  start.points.row(0) = mesh.points.row(first);
  start.points.row(first) = mesh.points.row(0);
  const std::vector<int> order = traversal_vertex_order(start);
  std::vector<int> new_index(order.size());
  Mesh out;
  out.points.resize(mesh.points.rows(), 3);
  for (std::size_t k = 0; k < order.size(); ++k) {
    new_index[order[k]] = static_cast<int>(k);
    out.points.row(static_cast<Eigen::Index>(k)) = start.points.row(order[k]);
  }
  out.faces = start.faces;
  for (auto& f : out.faces)
    for (int& v : f) v = new_index[v];
  const auto renumbered = [&](int v) { return new_index[swapped(v)]; };
  for (auto [a, b] : mesh.creases)
    out.creases.emplace_back(std::min(renumbered(a), renumbered(b)), std::max(renumbered(a), renumbered(b)));
  std::sort(out.creases.begin(), out.creases.end());
  for (int c : mesh.corners) out.corners.push_back(renumbered(c));
  std::sort(out.corners.begin(), out.corners.end());
  return out;
}

}  // namespace mm
