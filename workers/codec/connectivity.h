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
// Format version 2 changes three things. A popped gate (a, b) whose directed edge (b, a) is
// already held by a placed face has no symbol (in an oriented manifold nothing new lies across
// it, and both sides know it). A coded vertex's rank r means: 0 the next unseen number
// (`fresh`, the count of distinct vertices referenced so far); 1 escape to the index stream;
// 2 + 2k the anchor's k-th most recent neighbour, 3 + 2k the other gate vertex's. And plain
// indices are zigzag(index - fresh). A mesh numbered in order of first appearance in this
// traversal (mm::traversal_vertex_order) then codes each new vertex as rank 0 and closes fans
// with ranks 2 or 3. Version 1: ranks r >= 1 index the anchor's list oldest first, 0 escapes,
// plain indices are stored as they are.
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
