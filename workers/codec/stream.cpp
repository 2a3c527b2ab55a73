#include "codec/stream.h"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "codec/connectivity.h"
#include "codec/stream_detail.h"
#include "codec/stream_v3.h"
#include "support/atomic_file.h"

namespace mm {
namespace {

using codec_detail::kMaxKeyBytes;
using codec_detail::kMaxMetadataEntries;
using codec_detail::kMaxValueBytes;
using codec_detail::valid_key;

void validate_for_encoding(const Mesh& mesh, const CodecParams& params) {
  const std::string src = "encode";
  if (params.quant_bits < kMinQuantBits || params.quant_bits > kMaxQuantBits)
    throw InputError(src, "quantisation bits " + std::to_string(params.quant_bits) + " outside [" +
                              std::to_string(kMinQuantBits) + ", " + std::to_string(kMaxQuantBits) + "]");
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

void check_envelope(const std::uint8_t* data, std::size_t size, const std::string& source) {
  if (size >= 4 && std::memcmp(data, kMagic, 4) != 0)
    throw InputError(source, "not a meshmark stream (bad magic)");
  if (size < kMinBytesV3)
    throw InputError(source, "truncated: " + std::to_string(size) + " bytes, a stream has at least " +
                                 std::to_string(kMinBytesV3));
  if (size > kMaxStreamBytes) throw InputError(source, "stream larger than the 256 MiB limit");
  if (data[4] < kOldestVersion || data[4] > kVersion)
    throw InputError(source, "unsupported format version " + std::to_string(data[4]) +
                                 " (this build reads versions " + std::to_string(kOldestVersion) +
                                 " to " + std::to_string(kVersion) + ")");
  const std::size_t body = size - kChecksumBytes;
  std::uint32_t stored = 0;
  for (int i = 0; i < 4; ++i) stored |= static_cast<std::uint32_t>(data[body + i]) << (8 * i);
  if (checksum(data, body) != stored)
    throw InputError(source, "checksum mismatch: the stream is corrupted or truncated");
}

}  // namespace codec_detail

// ---------------------------------------------------------------------------------------------

std::vector<std::uint8_t> encode(const Mesh& mesh, const CodecParams& params) {
  validate_for_encoding(mesh, params);
  Quantization q;
  try {
    q = quantization_for(mesh.points, params.quant_bits);
  } catch (const InputError& e) {
    throw InputError("encode", e.reason());
  }
  const GridPoints grid = quantize(mesh.points, q);
  const auto edges = unique_edges(mesh);
  for (auto [a, b] : mesh.creases) {
    if (a > b) std::swap(a, b);
    const auto it = std::lower_bound(edges.begin(), edges.end(), std::make_pair(a, b));
    if (it == edges.end() || *it != std::make_pair(a, b))
      throw InputError("encode", "crease (" + std::to_string(a) + ", " + std::to_string(b) +
                                     ") is not an edge of the mesh");
  }
  return codec_detail::encode_v3(mesh, q, grid, params.metadata, nullptr,
                                 params.snap_cells.empty() ? nullptr : &params.snap_cells);
}

DecodedStream decode(const std::uint8_t* data, std::size_t size, const std::string& source) {
  codec_detail::check_envelope(data, size, source);
  return codec_detail::decode_v3(data, size, source);
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
  codec_detail::NullFaceSink none;
  codec_detail::encode_faces(mesh.faces, n, &traversal, none);
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
