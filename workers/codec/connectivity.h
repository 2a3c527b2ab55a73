// Face connectivity coding for the stream. The vertex order is fixed (the watermark depends on
// it), but the order of faces and the starting vertex of each face carry no meaning, so faces
// are coded by a breadth-first traversal over shared edges: each face is reached through a
// "gate" edge of an earlier face, so only its one or two remaining vertices are coded, mostly
// as a small rank among the already-known neighbours of a gate vertex.
//
// Traversal (encoder and decoder run the same one):
//   faces are put in canonical order (each rotated to start at its smallest vertex, then sorted);
//   while faces remain: if the gate queue is empty, the next unvisited canonical face starts a
//   new component (symbol 3 or 4, then its vertices as plain indices), and its edges (u, v) in
//   order become gates; otherwise a gate (a, b) is popped and the symbol says what lies across
//   it: 0 nothing new, 1 a triangle (b, a, x), 2 a quad (b, a, x, y); x is coded relative to a,
//   y relative to b: rank k >= 1 picks the k-th neighbour of that vertex in the order edges
//   became known, 0 escapes to a plain index. The new face's edges after (b, a) become gates.
//
// Format version 2 changes two things. Ranks count from the most recent neighbour of x's
// anchor (r = 1 is the last one known), and ranks beyond the anchor's list continue into the
// other gate vertex's list (most recent first), so a face closing a fan on either side costs a
// small rank instead of an escape. Plain indices: version 1 stores the index itself; version 2 stores
// zigzag(index - fresh), where fresh counts the distinct vertices referenced so far, so a mesh
// numbered in order of first appearance in this traversal (mm::traversal_vertex_order) stores
// only zeros there.
//
// Decoded faces come out in traversal order with that rotation; encoding them again gives the
// same bytes. Vertices that no face uses are fine (they just never appear here).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace mm::codec_detail {

struct ConnectivityStreams {
  std::vector<std::uint8_t> symbols;   // one byte per popped gate or component start
  std::vector<std::uint8_t> ranks;     // varint per coded vertex of a face reached by a gate
  std::vector<std::uint8_t> vertices;  // varint plain indices: component starts and escapes
};

// Faces must be triangles or quads with distinct in-range vertices (checked by the caller).
// Returns the streams and, in `traversal_order`, the faces as the decoder will produce them.
ConnectivityStreams encode_faces(const std::vector<std::vector<int>>& faces, int num_vertices,
                                 std::vector<std::vector<int>>* traversal_order, int version);

// Decodes exactly `num_faces` faces; every stream must be consumed exactly. Throws
// InputError(source, reason) for any inconsistency.
std::vector<std::vector<int>> decode_faces(const std::uint8_t* symbols, std::size_t symbols_size,
                                           const std::uint8_t* ranks, std::size_t ranks_size,
                                           const std::uint8_t* vertices, std::size_t vertices_size,
                                           std::uint32_t num_faces, int num_vertices,
                                           int version, const std::string& source);

}  // namespace mm::codec_detail
