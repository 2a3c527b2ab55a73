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
// A popped gate (a, b) whose directed edge (b, a) is already held by a placed face has no
// symbol (in an oriented manifold nothing new lies across it, and both sides know it). A coded
// vertex's rank r means: 0 the next unseen number (`fresh`, the count of distinct vertices
// referenced so far); 1 escape (FaceSink::escape); 2 + 2k the anchor's k-th most recent
// neighbour, 3 + 2k the other gate vertex's. Plain indices are zigzag(index - fresh). A mesh
// numbered in order of first appearance in this traversal (mm::traversal_vertex_order) then
// codes each new vertex as rank 0 and closes fans with ranks 2 or 3. The range coder codes the
// decisions with context models (codec/stream_v3.h).
//
// Decoded faces come out in traversal order with that rotation; encoding them again gives the
// same bytes. Vertices that no face uses are fine (they just never appear here).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace mm::codec_detail {

// What the traversal knows when it codes a decision: the range coder's contexts.
struct GateContext {
  int from_size = 3;     // size of the face whose edge the gate is
  int previous = 1;      // the previous gate symbol (1 before the first)
};
struct RankContext {
  bool fresh_possible = true;  // an unseen vertex number remains (rank 0 is allowed)
  int anchor_degree = 0;       // known neighbours of the anchor and of the other gate vertex
  int other_degree = 0;
  int second = 0;              // 1 for the second new vertex of a quad
  // The likeliest known vertices: the most recent neighbour of the anchor whose edge to it is
  // held by a placed face in the direction the new face does not use ("open"), so the new face
  // would close the anchor's fan; the same for the other gate vertex (triangles only).
  // hint_kind 0: neither exists, 1: both are the same vertex, 2: both exist and differ,
  // 3: only the anchor's, 4: only the other's. Hints are ranks.
  int hint_kind = 0;
  std::uint64_t hint_anchor = 0, hint_other = 0;
};

// Receives the traversal's decisions in order (encoder side).
class FaceSink {
 public:
  virtual ~FaceSink() = default;
  virtual void start(int size) = 0;                               // component start, 3 or 4
  virtual void index(std::uint64_t code) = 0;                     // plain index (as stored)
  virtual void symbol(int s, const GateContext& ctx) = 0;         // 0, 1 or 2
  virtual void rank(std::uint64_t r, const RankContext& ctx) = 0;
  // After rank 1: k < ring size picks entry k of the vertices two edges from the gate;
  // ring size + zigzag(index - fresh) otherwise.
  virtual void escape(std::uint64_t code) = 0;
  // false: the decisions' contexts are not needed (they cost a search of the neighbour lists).
  virtual bool wants_contexts() const { return true; }
};

// Supplies them (decoder side). Values are bounds-checked by the caller where it knows more;
// `max` arguments bound what a source may return. fail() throws InputError naming the source.
class FaceSource {
 public:
  virtual ~FaceSource() = default;
  virtual int start() = 0;
  virtual std::uint64_t index(std::uint64_t max) = 0;
  virtual int symbol(const GateContext& ctx) = 0;
  virtual std::uint64_t rank(const RankContext& ctx) = 0;
  virtual std::uint64_t escape(std::uint64_t max) = 0;
  [[noreturn]] virtual void fail(const std::string& reason) = 0;
};

// Runs the encoder's traversal, handing each decision to `sink`. Returns, in
// `traversal_order`, the faces as the decoder will produce them.
void encode_faces(const std::vector<std::vector<int>>& faces, int num_vertices,
                  std::vector<std::vector<int>>* traversal_order, FaceSink& sink);

// Decodes exactly `num_faces` faces from `source`.
std::vector<std::vector<int>> decode_faces(FaceSource& source, std::uint32_t num_faces,
                                           int num_vertices);

// A sink that drops the decisions: for the traversal order alone.
class NullFaceSink final : public FaceSink {
 public:
  void start(int) override {}
  void index(std::uint64_t) override {}
  void symbol(int, const GateContext&) override {}
  void rank(std::uint64_t, const RankContext&) override {}
  void escape(std::uint64_t) override {}
  bool wants_contexts() const override { return false; }
};

}  // namespace mm::codec_detail
