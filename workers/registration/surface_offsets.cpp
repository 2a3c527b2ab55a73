#include "registration/surface_offsets.h"

#include "registration/resync_context_impl.h"

namespace mm {

namespace {

// surface_offsets(), each sample's search started from its triangle in `starts` (another
// reading's answers; empty: none), which then holds this reading's: a second reading of the same
// samples in a nearby frame costs a fraction of the first. Starts change no answer but a tie's.
SurfaceOffsets offsets_from(const ResyncContext& context, const Mesh& suspect, const Similarity& to_control_frame,
                            int max_samples, double max_distance, std::vector<int>& starts) {
  using registration_detail::strided;
  using registration_detail::Trip;
  const ResyncContext::Impl& ctx = context.impl();
  const FitSurface& fit = ctx.fit();
  const LevelData& level = ctx.level(ctx.fit_level);
  const SparseOperator& S = level.op.S;
  const Points moved = to_control_frame.apply(strided(suspect.points, max_samples));
  const double max_d = max_distance * ctx.diagonal;

  std::vector<Trip> t;
  std::vector<Eigen::Vector3d> normals;
  std::vector<double> offsets;
  std::vector<Eigen::Vector3d> points;
  starts.resize(static_cast<std::size_t>(moved.rows()), -1);
  for (Eigen::Index k = 0; k < moved.rows(); ++k) {
    const Eigen::Vector3d q = moved.row(k).transpose();
    if (!q.allFinite()) continue;
    int& start = starts[static_cast<std::size_t>(k)];
    const TriangleHit h = fit.tree->closest(q, start);
    start = h.triangle;
    if (!(h.distance <= max_d)) continue;
    const auto& f = fit.tris[static_cast<std::size_t>(h.triangle)];
    const Eigen::Vector3d p0 = level.points.row(f[0]), p1 = level.points.row(f[1]), p2 = level.points.row(f[2]);
    const Eigen::Vector3d normal = (p1 - p0).cross(p2 - p0).normalized();
    if (!normal.allFinite()) continue;
    const int row = static_cast<int>(offsets.size());
    for (int c = 0; c < 3; ++c)
      if (h.barycentric[c] != 0) t.emplace_back(row, f[c], h.barycentric[c]);
    normals.push_back(normal);
    offsets.push_back((q - h.point).dot(normal));
    points.push_back(h.point);
  }
  SurfaceOffsets out;
  const int m = static_cast<int>(offsets.size());
  // Each row is the barycentric mix of three refined vertices' rows of S: W S, one sparse product.
  SparseOperator W(m, S.rows());
  W.setFromTriplets(t.begin(), t.end());
  out.rows = W * S;
  out.normals.resize(m, 3);
  for (int i = 0; i < m; ++i) out.normals.row(i) = normals[static_cast<std::size_t>(i)].transpose();
  out.offsets = Eigen::Map<const Eigen::VectorXd>(offsets.data(), m);
  out.nuisance.resize(m, 7);
  // About the control's centroid, so the rotation and scale columns are not nearly the others.
  const Eigen::Vector3d centre = ctx.control.points.colwise().mean().transpose();
  for (int i = 0; i < m; ++i) {
    const Eigen::Vector3d& nv = normals[static_cast<std::size_t>(i)];
    const Eigen::Vector3d p = points[static_cast<std::size_t>(i)] - centre;
    out.nuisance.block<1, 3>(i, 0) = nv.transpose();
    out.nuisance.block<1, 3>(i, 3) = p.cross(nv).transpose();
    out.nuisance(i, 6) = nv.dot(p);
  }
  return out;
}

SurfaceOffsets without_nuisance(SurfaceOffsets s) {
  s.nuisance.resize(s.offsets.size(), 0);
  return s;
}

}  // namespace

SurfaceOffsets surface_offsets(const ResyncContext& context, const Mesh& suspect, const Similarity& to_control_frame,
                               int max_samples, double max_distance) {
  std::vector<int> starts;
  return offsets_from(context, suspect, to_control_frame, max_samples, max_distance, starts);
}

SurfaceOffsets surface_in_frame(const ResyncContext& context, const Mesh& suspect) {
  return without_nuisance(surface_offsets(context, suspect, Similarity()));
}

std::vector<SurfaceOffsets> surface_readings(const ResyncContext& context, const Mesh& suspect,
                                             const Similarity& to_control_frame) {
  std::vector<int> starts;
  std::vector<SurfaceOffsets> out;
  out.push_back(without_nuisance(
      offsets_from(context, suspect, Similarity(), kSurfaceOffsetSamples, kSurfaceOffsetDistance, starts)));
  out.push_back(offsets_from(context, suspect, to_control_frame, kSurfaceOffsetSamples, kSurfaceOffsetDistance, starts));
  return out;
}

}  // namespace mm
