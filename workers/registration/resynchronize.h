// Resynchronisation: a suspect mesh brought back to the original control polyhedron's vertex
// order and frame, so non-blind extraction (watermark/watermark.h, extract) can compare the two
// vertex by vertex. The mark lives in the control polyhedron's spectrum, so what is recovered is
// always a control polyhedron: control.num_vertices() points in the control's order.
//
// Suspects handled, tried in this order:
//  - "polyhedron": the (watermarked) control polyhedron itself, maybe quantised by the codec,
//    rescaled, rotated or shifted. Same vertex count and faces as sets (the codec reorders faces
//    and rotates each face's first vertex): vertices correspond by index.
//  - "subdivided": the control polyhedron refined L levels by build_subdivision/subdivide, maybe
//    triangulated, noisy, moved. Vertex count equal to the level-L count: with consistent faces
//    vertices correspond by index; otherwise (an STL file welds vertices and numbers them by first
//    appearance) each is matched to its mutual nearest original refined vertex after alignment,
//    then again to the refined vertices of the estimate (the mark moves them).
//    Then x solves min |S_L x - p| through the precomputed Cholesky factor of S_L^T S_L, which
//    averages noise over the 4^L-fold redundant refined vertices. The same matching at L = 0
//    recognises a polyhedron whose order was lost.
//    In the original's numbering, the same count and faces also arise from the level L-1 copy
//    subdivided once more by the plain scheme (a decoded file has no crease tags): that
//    hypothesis, T = untagged step * S_{L-1}, is solved too and kept when its residual is smaller
//    (`resubdivided`).
//  - "piece": a piece cut from a subdivided copy as issued (a crop): fewer vertices than any
//    level, each a refined vertex of the level its edge lengths name, in the original's frame.
//    Paired unmoved with those refined vertices and solved from the pairs alone; control points
//    the piece does not reach stay at the original's positions. Only for pieces the pairs explain
//    to float precision; a noisy or simplified piece goes to the surface fit.
//  - "surface-fit": anything else (remeshed, re-tessellated). Similarity ICP against the original
//    refined surface, then a few rounds of a linear point-to-plane fit of the control points with
//    the original's topology, closest-point pairs both ways (as fitting/fit_control_points),
//    pulled towards the original control points rather than smoothed: a Laplacian would erase
//    the high-frequency mark. Only the mark's normal component is observable on a surface.
//    A suspect that covers part of the original (a crop, remeshed or noisy) is aligned by
//    suspect-to-original pairs alone, rigidly from the original's frame, when those explain it
//    far better than the two-way pairs, which drag it towards covering everything.
// Alignment uses 7 degrees of freedom (scale, rotation, translation) fitted to many
// correspondences, then re-estimated on the recovered control points with a spectrum-flattening
// weight (fit_similarity_preserving_mark), so it takes little of the mark with it.
// Measured behaviour and limits: docs/registration.md.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "meshio/mesh.h"
#include "registration/align_similarity.h"
#include "subdivision/subdivide.h"

namespace mm {

struct ResyncOptions {
  int max_level = 4;             // highest subdivision level recognised (capped by the context's)
  bool align = true;             // fit a similarity; false: the suspect is in the control's frame
  std::string source = "suspect mesh";  // names the suspect in InputError messages
  // Order-free matching ("subdivided"/"polyhedron" with lost order): accepted when mutual
  // nearest-neighbour pairs cover at least this fraction of the original refined vertices
  // after the matching rounds (pairing again with the estimate).
  double min_matched_fraction = 0.9;
  // ...and tried when the first pairs, made with the unmarked original vertices, cover this
  // much: a mark plus noise of a fair fraction of the vertex spacing leaves some unpaired that
  // the rounds recover (abc5's polyhedron at level 3, marked, noise 5e-4, welded: 87.6 % at
  // first, 99.4 % after). A suspect that is not the same vertices (a remesh) still has to pair
  // min_matched_fraction after the rounds, or it goes to the surface fit as before.
  double min_start_fraction = 0.8;
  double count_tolerance = 0.02;  // relative vertex-count difference still tried by matching
  int matching_rounds = 10;       // at most: solve, pair again with the estimate S x while pairs grow
  IcpOptions icp;
  // Surface fit.
  int suspect_samples = 10000;   // per kind: suspect vertices, area samples, refined vertices paired
  int alignment_samples = 4000;  // samples of each surface used by the similarity ICP
  double regularization = 1e-3;  // pull towards the original control points / mean data weight
  double max_distance = 0.02;    // correspondences farther than this x diagonal are ignored
  // Also try "level L-1, then one untagged smooth step" for in-order suspects at level L >= 1
  // (false: the creased hypothesis only, as before; for experiments).
  bool consider_resubdivision = true;
  bool force_surface_fit = false;  // skip recognition (experiments, suspects known to be remeshed)
  // In-order subdivided suspects: model a leaker's Laplacian smoothing from the original
  // (registration/smoothing_model.h) and take its change of the original out before solving.
  bool model_smoothing = true;
  int fit_iterations = 3;        // pairing / solve rounds against the current estimate
  std::uint64_t seed = 1;        // sampling is deterministic for a given seed
};

struct Resynchronized {
  Points points;             // control.num_vertices() x 3, in the control's frame and vertex order
  std::string method;        // "polyhedron", "subdivided", "piece", "surface-fit"
  int level = 0;             // subdivision level recognised ("subdivided", "piece"), else 0
  double residual_rms = 0;   // RMS of the data the solution could not explain (suspect points or
                             // closest-point distances, after alignment) / control bbox diagonal
  double matched_fraction = 1;   // suspect data used: matched vertices or accepted samples
  Similarity to_control_frame;   // maps the suspect into the control's frame
  bool order_recovered = false;  // vertices matched by nearest neighbour (order was lost)
  // "subdivided" at level L >= 1 explained better as the level L-1 copy refined once more
  // without crease or corner tags (subdivide() on a decoded file): points solved with that
  // operator. Only for suspects in the original's numbering (order_recovered = false).
  bool resubdivided = false;
  // The attack modelled from the original and taken out ("umbrella smoothing, lambda 0.5 x 10"),
  // "" when none was.
  std::string attack_model;
};

// Everything that depends only on the original control polyhedron (subdivision operators and
// factorised normal equations per level, refined original surfaces, AABB trees), for one asset.
// Each level, and the fit surface, is built on first use: resynchronize() builds only the level
// the suspect's vertex count names (and the one below, for the re-subdivided hypothesis) or the
// fit surface; level 4 alone is about three quarters of all levels. Once built nothing changes,
// so a context is safe to share between threads (a level two threads ask for at once is built
// once, the second waits). Results do not depend on what was built before.
class ResyncContext {
 public:
  // control: original polyhedron with creases/corners, in the frame results are wanted in.
  // fit_level: subdivision level of the original surface that remeshed suspects are fitted
  // against (clamped to [1, max_level]). Throws InputError for an unusable control mesh (its
  // topology is checked here) and std::invalid_argument for max_level outside
  // [0, kMaxSubdivisionLevels]. A level whose normal equations are singular throws InputError
  // when it is first needed.
  ResyncContext(const Mesh& control, int max_level = 4, int fit_level = 3);
  ~ResyncContext();
  ResyncContext(ResyncContext&&) noexcept;
  ResyncContext& operator=(ResyncContext&&) noexcept;

  const Mesh& control() const;
  int max_level() const;
  int fit_level() const;
  double diagonal() const;  // control bounding-box diagonal
  int vertex_count(int level) const;  // of the refined original, known without building it
  // Level 0 is the control itself; levels 1..max_level() the refined original (built if needed;
  // std::out_of_range outside [0, max_level()]).
  const SubdivisionOperator& subdivision(int level) const;
  const Points& refined_points(int level) const;
  bool level_built(int level) const;
  void build_all() const;  // every level and the fit surface now (benchmarks, measurements)
  // Approximate heap bytes held, growing as levels are built (a cache budgets with it).
  std::size_t memory_bytes() const;

  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

// Throws InputError(options.source, reason) for unusable suspects (no vertices or faces,
// non-finite coordinates, bad indices, nothing matched).
Resynchronized resynchronize(const ResyncContext& context, const Mesh& suspect,
                             const ResyncOptions& options = {});

}  // namespace mm
