// The initial control polyhedron: the input decimated (OpenMesh's Decimater, halfedge
// collapses, so every control vertex starts on an input vertex) while the feature network is
// kept: corners never move, a crease vertex may only collapse onto its neighbour along its own
// crease, and every crease polyline keeps enough vertices to stay a curve. The surviving sharp
// edges become the infinitely sharp creases and the corners the corner tags of the result.
#pragma once
#include <memory>
#include <vector>

#include "fitting/segmentation.h"
#include "fitting/sharp_features.h"
#include "meshio/mesh.h"

namespace mm {

struct ControlOptions {
  int target_vertices = 100;  // decimation stops here (or earlier when nothing legal is left)
  int min_open_chain_interior = 0;  // vertices kept inside a crease polyline between two corners
  int min_closed_loop = 4;          // vertices kept on a closed crease loop without corners
  double max_normal_deviation_degrees = 60.0;  // rejects collapses that fold faces over
  // Rejects collapses leaving a triangle longer than this times its height, unless they improve
  // it: slivers make the subdivision surface ripple. 0 disables.
  double max_aspect_ratio = 8.0;
  // Triangles whose three corners lie on the feature network (a strip between creases: an
  // extrusion wall, a step, the annulus between concentric rims; a disc inside a crease loop)
  // are exempt from the aspect-ratio guard unless this is set: their shape follows the creases,
  // and guarding them kept the ABC parts' rims at hundreds of vertices.
  bool aspect_ratio_on_feature_triangles = false;
  // Per input vertex: multiplies the cost of collapses there (empty = all 1). The fitting loop
  // raises it where the fitted surface stays too far away, so the next decimation keeps more
  // control vertices in those regions.
  std::vector<double> importance;
};

struct ControlPolyhedron {
  Mesh mesh;                    // triangles; creases (i < j) and corners set
  std::vector<int> source;      // per control vertex: the input vertex it started on
  int split_vertices = 0;       // input vertices duplicated to make a non-manifold input manifold
};

// `mesh` should be normalised (unit box); `features`/`segmentation` are those of `mesh`.
// Throws std::invalid_argument when the mesh has no usable faces.
ControlPolyhedron build_control_polyhedron(const Mesh& mesh, const Features& features,
                                           const Segmentation& segmentation,
                                           const ControlOptions& options);

// The same for a sequence of calls on one mesh (compress()'s rounds). A greedy decimation
// stopped at N vertices is the start of the same decimation to fewer, so a call whose options
// equal the previous call's but for a target not larger continues that decimation instead of
// starting again from the input: the same result for less work. `mesh`, `features` and
// `segmentation` must outlive this object.
class ControlDecimation {
 public:
  ControlDecimation(const Mesh& mesh, const Features& features, const Segmentation& segmentation);
  ~ControlDecimation();
  ControlDecimation(const ControlDecimation&) = delete;
  ControlDecimation& operator=(const ControlDecimation&) = delete;
  ControlPolyhedron build(const ControlOptions& options);

 private:
  ControlPolyhedron extract() const;
  void build_input();  // the input as an OpenMesh mesh with its flags, once
  struct Impl;
  std::unique_ptr<Impl> impl_;
  const Mesh& mesh_;
  const Features& features_;
  const Segmentation& segmentation_;
};

}  // namespace mm
