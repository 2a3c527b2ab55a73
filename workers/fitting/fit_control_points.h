// Least-squares fitting of control point positions so that the subdivided surface approximates a
// target mesh (the paper's approximation step, section III-B). The control topology (faces,
// creases, corners) is fixed; only positions move. Each iteration builds closest-point
// correspondences in both directions -- target samples to the subdivided surface and subdivided
// vertices to the target, so neither thin features nor overshoot are missed -- with crease points
// matched against the target's sharp edges only, then solves one sparse linear system for x, y, z.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "fitting/sharp_features.h"
#include "meshio/mesh.h"

namespace mm {

struct FitOptions {
  int levels = 3;             // subdivision levels of the surface being fitted
  int iterations = 6;         // correspondence / solve rounds
  int area_samples = 3000;    // random target surface samples added to the target vertices
  int max_vertex_samples = 5000;  // target vertices used per iteration (all for the final error)
  double crease_weight = 8.0; // weight of crease correspondences relative to surface ones
  double smoothness = 1e-4;   // umbrella-Laplacian regularisation (relative to the data term)
  // From the second iteration on, a correspondence at distance d weighs 1 + reweight (d / rms)^2
  // times its weight (the extra at most 10), rms being the last iteration's: the largest
  // distances, which the tolerance is on, pull harder than least squares lets them (iteratively
  // reweighted least squares).
  // 0: plain least squares. compress() sets it without coarsening (compress.cpp, kReweight).
  double reweight = 0;
  std::uint64_t seed = 1;     // sampling is deterministic for a given seed
  // Charge the refined triangles' centroids' distances to FitResult::region_error too (where a
  // triangle cuts across a notch of the part that no vertex shows). Off for a fit at a coarser
  // level than the surface it steers, whose larger triangles would overstate those distances.
  bool face_interiors = true;
};

// Distances between the subdivided surface and the target, in the target's units.
struct FitStats {
  double hausdorff = 0;  // max of both one-sided maxima (sample based)
  double rms = 0;        // root mean square of both directions' distances
  double mean = 0;
  double diagonal = 0;   // target bounding box diagonal: divide by it for relative numbers
};

struct FitResult {
  Mesh control;                       // same topology as the input control, fitted positions
  FitStats stats;
  std::vector<double> vertex_error;   // per control vertex: largest distance it is responsible for
  std::vector<double> target_error;   // per target vertex: distance to the subdivided surface
  // per target vertex: the larger of target_error and the distances from the subdivided surface
  // measured to the target triangles around it (where the surface overshoots the part)
  std::vector<double> region_error;
};

// What a fit needs of the target (its AABB trees and samples), built once and reused by every
// fit against it (compress() fits several control meshes to one target).
class FitTarget {
 public:
  // `features` are the target's (sharp edges give the crease samples); everything needed is
  // copied. The sampling options (seed, area_samples, max_vertex_samples) are fixed here.
  FitTarget(const Mesh& target, const Features& features, const FitOptions& options = {});
  ~FitTarget();
  // The target's bounding-box diagonal: what FitStats::diagonal holds for every fit against it.
  double diagonal() const;
  FitTarget(const FitTarget&) = delete;
  FitTarget& operator=(const FitTarget&) = delete;
  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  friend FitResult fit_control_points(const Mesh&, const FitTarget&, const FitOptions&);
};

// `target_features` are the target's (sharp edges give the crease samples).
FitResult fit_control_points(const Mesh& control, const Mesh& target,
                             const Features& target_features, const FitOptions& options = {});
// The same against a prepared target; throws std::invalid_argument when `options` samples
// differently from those the target was prepared with.
FitResult fit_control_points(const Mesh& control, const FitTarget& target, const FitOptions& options = {});

// How the fit samples its target, as a cache key part (";crease-spacing=1/600"): a stored
// polyhedron fitted from other samples is fitted again (jobs/prepared_asset.cpp).
std::string fit_sampling_key();

// The same distance statistics for a given control mesh, without moving anything.
FitStats measure_fit(const Mesh& control, int levels, const Mesh& target);

}  // namespace mm
