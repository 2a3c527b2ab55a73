// The .mmc stream: a control polyhedron (triangles and quads, sharp creases, corners) with
// quantised positions, entropy coded by an adaptive range coder with context models
// (codec/stream_v3.h) and sealed by a CRC-32.
// docs/stream-format.md describes it byte by byte.
//
// Vertex order is kept exactly: the watermark lives in the spectrum of this vertex order.
// Face order and each face's first vertex carry no meaning and are not kept (faces come back in
// the connectivity coder's traversal order, orientation intact; codec/connectivity.h). Creases
// are stored as a set over the mesh's edges and corners as a set, so both come back sorted and
// without duplicates. Encoding a decoded stream again reproduces it byte for byte.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "codec/quantize.h"
#include "meshio/mesh.h"

namespace mm {

struct CodecParams {
  int quant_bits = 12;                        // [kMinQuantBits, kMaxQuantBits]
  // Small key-value strings (asset id, copy id...). Keys: 1..64 bytes of [A-Za-z0-9_.-];
  // values: up to 1024 bytes; at most 32 entries. Never put secrets here.
  std::map<std::string, std::string> metadata;
  // Rate-distortion snapping, opt-in (empty: off, the default). Per coordinate
  // (x, y, z of vertex 0, then of vertex 1, ...: 3 entries per vertex), how many grid cells it
  // may move away from its nearest grid value when a value within that reach is cheaper to code
  // (the prediction, a neighbour's value to copy, a smaller residual). Spends error the caller
  // has to spare on bytes: nothing here looks at the surface, so the caller measures the decoded
  // result. Never for watermarked polyhedra, whose small deliberate perturbations it would erase.
  std::vector<std::uint8_t> snap_cells;
};

struct DecodedStream {
  Mesh mesh;                 // positions = dequantize(grid, quantization), in the part's units
  GridPoints grid;           // the quantised values, exactly as stored
  Quantization quantization;
  std::map<std::string, std::string> metadata;
  int version = 0;
};

// Hard limits the decoder enforces before allocating anything.
constexpr std::size_t kMaxStreamBytes = 256u << 20;    // whole stream and decompressed payload
constexpr std::uint32_t kMaxStreamVertices = 1u << 24;
constexpr std::uint32_t kMaxStreamFaces = 1u << 25;

// Encodes a mesh whose faces are all triangles or quads with distinct in-range vertices, whose
// creases are edges of its faces and whose corners are vertex indices. Throws InputError
// ("encode", reason) otherwise, and for bad parameters or metadata.
std::vector<std::uint8_t> encode(const Mesh& mesh, const CodecParams& params = {});

// Decodes and validates a stream. Any defect (wrong magic or version, truncation, checksum
// mismatch, sizes beyond the limits or beyond the bytes present, bad indices, creases that are
// not edges, trailing bytes...) throws InputError(source, reason); nothing is allocated beyond
// what the present bytes justify.
DecodedStream decode(const std::uint8_t* data, std::size_t size, const std::string& source);
inline DecodedStream decode(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  return decode(bytes.data(), bytes.size(), source);
}

// Files: written to a temporary file in the same folder, fsynced and renamed into place;
// read with a size check against kMaxStreamBytes first. Both throw InputError(path, reason).
void write_stream_file(const std::string& path, const std::vector<std::uint8_t>& bytes);
std::vector<std::uint8_t> read_stream_file(const std::string& path);
DecodedStream decode_file(const std::string& path);

// A vertex numbering the stream codes cheaply: order[k] = the vertex that should become vertex
// k, in order of first appearance in the connectivity coder's face traversal (unused vertices
// last). Producers free to choose their vertex order (compress) renumber with it; the codec
// itself never reorders. Faces must be valid for encode().
std::vector<int> traversal_vertex_order(const Mesh& mesh);

// `mesh` renumbered by traversal_vertex_order, the traversal starting at vertex `first` (the
// traversal starts at vertex 0's first face in canonical order, so `first` is made vertex 0
// before). Creases and corners follow and stay sorted. The same surface; the stream's size
// depends on the start by a few per cent (its predictions and ranks follow the traversal).
Mesh in_traversal_order(const Mesh& mesh, int first = 0);

}  // namespace mm
