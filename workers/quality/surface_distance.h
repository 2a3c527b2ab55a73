// Distances between two surfaces, as the compression targets are stated: symmetric Hausdorff,
// RMS and mean distance, absolute and relative to the bounding-box diagonal of the first mesh.
// Each surface is sampled densely (area-weighted, seeded, plus its vertices) and every sample is
// measured to the closest point of the other surface with an AABB tree (CGAL).
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct SamplingParams {
  int samples = 200000;        // area-weighted samples per surface (on average), besides its vertices
  std::uint64_t seed = 1;      // same seed, same samples, same numbers
  bool include_vertices = true;
};

// Distances from the samples of one surface to the other surface.
struct OneSidedDistance {
  double max = 0, mean = 0, rms = 0;
  std::size_t samples = 0;
};

struct SurfaceDistance {
  OneSidedDistance a_to_b, b_to_a;
  // Symmetric values: the larger of the two directions for each statistic (so a missing part
  // on either side shows).
  double hausdorff = 0, rms = 0, mean = 0;
  double diagonal = 0;  // bounding-box diagonal of mesh a
  double hausdorff_relative() const { return hausdorff / diagonal; }
  double rms_relative() const { return rms / diagonal; }
  double mean_relative() const { return mean / diagonal; }
};

// Area-weighted points on the surface: each triangle gets its area's share of `samples`, rounded
// up or down at random, uniform within it, drawn from a stream seeded by the seed and the
// triangle's own corners, so the same surface gives the same set of samples whatever the order of
// its faces, the numbering of its vertices or the corner each face starts at. Polygons are split
// into fans (so a polygon's surface itself depends on its first corner). Throws
// InputError("quality", reason) when the mesh has no face of positive area or bad indices or
// coordinates.
std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, int samples, std::uint64_t seed,
                                            bool include_vertices);

// The points' indices along a Morton (Z-order) curve through their bounding box, ties by index:
// queried in this order, each closest-point query starts near its answer (the previous one's).
std::vector<int> spatial_order(const std::vector<Eigen::Vector3d>& points);

// One surface's side of repeated measurements against it (the part, in a compress run that
// measures a dozen candidate surfaces against it): its samples and its closest-point tree, built
// once (on fandisk about a sixth of a measurement), so a measurement builds only the other
// surface's. The overloads taking one give the numbers of those taking its mesh and params, bit
// for bit, and throw what they throw: the samples and tree are built by the first measurement
// (so a caller may make one before it has validated the mesh), once, whichever thread measures
// first; threads may share one, and copies share it.
class TriangleDistanceTree;
class MeasuredSurface {
 public:
  explicit MeasuredSurface(const Mesh& mesh, const SamplingParams& params = {});
  ~MeasuredSurface();
  const Mesh& mesh() const;
  const SamplingParams& params() const;
  double diagonal() const;  // of the mesh's bounding box
  // Its closest-point tree and its samples (sample_surface with params()), built on first use.
  const TriangleDistanceTree& tree() const;
  const std::vector<Eigen::Vector3d>& samples() const;
  // The samples' indices in the order a measurement queries most of them in: along a curve
  // through space, so that each query starts from a nearby sample's answer.
  const std::vector<int>& sample_order() const;
  struct Impl;
  // For the measurement code (surface_distance.cpp): besides the above, the layouts of the trees
  // of the last few surfaces measured against this one, so a surface that moves the same
  // triangles a little (a control polyhedron's streams at several grids) reuses its tree's split.
  const Impl& impl() const { return *impl_; }

 private:
  std::shared_ptr<const Impl> impl_;
};

OneSidedDistance one_sided_distance(const Mesh& from, const Mesh& to, const SamplingParams& params = {});
SurfaceDistance surface_distance(const Mesh& a, const Mesh& b, const SamplingParams& params = {});

// surface_distance for a caller that only needs it when the symmetric Hausdorff distance is at
// most `limit` times a's diagonal (a tolerance check): nothing as soon as one sample lies
// farther, which then proves it larger. The samples are measured every 64th first, then every
// 16th, 4th and the rest, so a surface far off is turned away after a few of them (in the
// compress search a third of the measurements are); within the limit the numbers are
// surface_distance's, bit for bit (a sample's distance does not depend on the order, and the
// statistics are summed in sample order). An infinite limit measures everything.
std::optional<SurfaceDistance> surface_distance_within(const Mesh& a, const Mesh& b, double limit,
                                                       const SamplingParams& params = {});
std::optional<SurfaceDistance> surface_distance_within(const MeasuredSurface& a, const Mesh& b, double limit);

// What a receiver of a control polyhedron sees against the part it stands for: `control`
// subdivided `levels` times (subdivision/decompress.h), measured from `part` as above. The one
// measurement behind compress's tolerance, its bit choice and protect jobs.
SurfaceDistance decoded_distance(const Mesh& part, const Mesh& control, int levels,
                                 const SamplingParams& params = {});
SurfaceDistance decoded_distance(const MeasuredSurface& part, const Mesh& control, int levels);
// The same, or nothing once it is known to exceed `limit` (surface_distance_within).
std::optional<SurfaceDistance> decoded_distance_within(const Mesh& part, const Mesh& control, int levels,
                                                       double limit, const SamplingParams& params = {});
std::optional<SurfaceDistance> decoded_distance_within(const MeasuredSurface& part, const Mesh& control, int levels,
                                                       double limit);

// Only the answer of a tolerance check: whether surface_distance(a, b).hausdorff_relative() is at
// most `limit`, exactly (the same comparison on the same samples), without the numbers: a sample
// is measured only when no triangle of the other surface lies certainly within the limit, so a
// surface that meets it costs its samples and its tree, not a closest-point search per sample
// (about a fifth of a whole measurement; compress makes a dozen such checks per run and measures
// only the stream it writes). Same errors as surface_distance.
bool surface_within(const MeasuredSurface& a, const Mesh& b, double limit);
// The same for `control` subdivided `levels` times: what a CompressOptions::verify for the
// tolerance `limit` answers.
bool decoded_within(const MeasuredSurface& part, const Mesh& control, int levels, double limit);

}  // namespace mm
