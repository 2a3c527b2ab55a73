// Similarity alignment (uniform scale, rotation, translation: 7 degrees of freedom) of a suspect
// to an original. The watermark is a small, spatially varying displacement; a 7-DOF transform
// fitted to many correspondences can only remove its (tiny) projection on a global rescale,
// rotation and shift, so the mark survives alignment.
#pragma once
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

// p' = scale * p * R^T + t for row points p.
struct Similarity {
  double scale = 1;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::RowVector3d translation = Eigen::RowVector3d::Zero();

  Eigen::RowVector3d apply(const Eigen::RowVector3d& p) const;
  Points apply(const Points& p) const;
  Similarity inverse() const;
  // The transform that applies `first`, then this one.
  Similarity after(const Similarity& first) const;
};

// Least-squares similarity mapping src rows onto dst rows (Umeyama 1991), optionally weighted
// (weights >= 0, same length as the rows). Reflections are excluded. fixed_scale > 0: the scale is
// that, and rotation and translation are fitted (a rigid motion of the scaled rows). Throws
// std::invalid_argument for mismatched sizes or fewer than 3 rows of positive weight.
Similarity fit_similarity(const Points& src, const Points& dst, const Eigen::VectorXd* weights = nullptr,
                          double fixed_scale = 0);

// Similarity mapping `moved` -- the vertices of `original` in another frame, plus a small
// displacement such as a watermark and noise -- back onto `original`, estimated so that the
// displacement is not absorbed. A plain least-squares fit weighs each spectral coefficient by its
// square, so the few largest, lowest-frequency ones (which Method 1 scales by 1 +- a) decide the
// scale and rotation and take a sizeable share of the mark with them. Here rotation and scale
// come from the Laplacian coordinates K x (K = D - A of original's connectivity: coefficient k
// weighted by its eigenvalue, which flattens the spectrum), regressing the copy on the original
// because noise and mark sit in the copy; the translation comes from the centroids, which the
// mark never moves (the zero-eigenvalue coefficients are left alone). Throws
// std::invalid_argument for a row count mismatch or a mesh without edges.
Similarity fit_similarity_preserving_mark(const Mesh& original, const Points& moved);

// Closest point of the fixed shape (a point set or a surface) to a query; `row` is the moving
// point's row, so a surface query can start from that row's previous answer (ICP moves it little).
using ClosestPoint = std::function<Eigen::Vector3d(const Eigen::Vector3d& q, Eigen::Index row)>;

struct IcpOptions {
  int iterations = 40;         // correspondence / fit rounds of the final refinement
  int probe_iterations = 8;    // rounds per start when choosing among starting transforms
  int probe_points = 1500;     // evenly strided subset of the moving points used while probing
  double trim_fraction = 0.1;  // worst correspondences ignored in each fit (outliers, holes)
  double tolerance = 1e-12;    // stop when the relative change of the trimmed RMS is below this
  // Rigid: keep the starting transform's scale. One-way pairs (no fixed samples) with a free
  // scale can shrink the moving points onto a flat patch of the fixed surface.
  bool keep_scale = false;
};

struct IcpResult {
  Similarity transform;        // maps the moving points onto the fixed shape
  double rms = 0;              // trimmed RMS closest-point distance after alignment
  int iterations = 0;
};

// Iterative closest point with a similarity fit per round, from one starting transform. Pairs go
// both ways: each moving point to its closest point on the fixed shape and, when fixed_samples is
// not empty, each fixed sample to its nearest (transformed) moving point, so the scale cannot
// shrink the moving points onto a small part of the fixed shape.
IcpResult icp_similarity(const Points& moving, const ClosestPoint& closest, const Points& fixed_samples,
                         const Similarity& start, const IcpOptions& options = {}, int iterations = -1);

// Starting transforms from the two shapes' moments (evenly spread samples of each): centroids,
// RMS radii and the principal axes with the four proper sign choices, the same without rotation,
// and the identity (the suspect may already be in the original's frame).
std::vector<Similarity> moment_starts(const Points& moving_samples, const Points& fixed_samples);

// Probes every start with a short ICP, refines the best one fully.
IcpResult align_similarity(const Points& moving, const Points& moving_samples,
                           const Points& fixed_samples, const ClosestPoint& closest,
                           const IcpOptions& options = {});

// Closest point of a surface to a query and the surface's unit normal there.
struct SurfacePoint {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
};
using ClosestOnSurface = std::function<SurfacePoint(const Eigen::Vector3d& q, Eigen::Index row)>;

// Rigid ICP (the starting transform's scale kept) minimising point-to-plane distances, with the
// rotation linearised each round (Chen and Medioni 1992): pairs may slide along the surface, so
// it settles in a few rounds where point-to-point ICP creeps for tens. `rms` is the trimmed RMS
// closest-point distance, as icp_similarity's.
IcpResult icp_rigid_point_to_plane(const Points& moving, const ClosestOnSurface& closest, const Similarity& start,
                                   const IcpOptions& options = {});

}  // namespace mm
