#include "registration/resync_context_impl.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <optional>
#include <array>
#include <cmath>
#include <atomic>
#include <mutex>
#include <random>
#include <stdexcept>

#include "geometry/closest_point.h"
#include "geometry/normal_weighted_grams.h"
#include "geometry/nearest_neighbours.h"

namespace mm::registration_detail {

// Reverse pairs farther than this many times the forward pairs' RMS distance are not covered by
// the suspect (noise and the mark keep covered ones within about twice it).
constexpr double kCoverage = 4;
// A suspect-to-original alignment replaces the two-way one when its RMS is below this share.
constexpr double kPartialGain = 0.5;
// The asset's own frame is kept while it explains the suspect within this factor of the best
// pose: copies are issued there, and a part symmetric about an axis fits as well turned over
// (abc5, abc7, abc9 remeshed settled on poses turned by 1.2-3.1 rad, and the mark was read in
// the wrong places), while a similarity also takes up some of the mark's lowest frequencies.
constexpr double kFrameTolerance = 2;

Resynchronized surface_fit(const ResyncContext::Impl& ctx, const Mesh& suspect, const ResyncOptions& o) {
  Resynchronized r;
  r.method = "surface-fit";
  const auto tris = triangle_list(suspect);
  const TriangleIndex suspect_tree(suspect.points, tris);
  if (suspect_tree.empty()) throw InputError(o.source, "no face of positive area");
  // The data is far more redundant than the 3n unknowns: a capped, evenly strided share of it.
  const Points samples = stack(strided(suspect.points, o.suspect_samples),
                               sample_area(suspect.points, tris, o.suspect_samples, o.seed));

  const FitSurface& fit = ctx.fit();
  if (o.align) {
    HintedClosest hinted(*fit.tree);
    const ClosestPoint closest = [&hinted](const Eigen::Vector3d& q, Eigen::Index row) { return hinted.closest(q, row).point; };
    const Points moving = sample_area(suspect.points, tris, o.alignment_samples, o.seed + 1);
    const Points fixed = strided(fit.samples, o.alignment_samples);
    r.to_control_frame = align_similarity(moving, moving, fixed, closest, o.icp).transform;
    // A crop covers part of the original: pairing the original's samples with it (above) drags
    // the similarity towards covering everything. Suspect-to-original pairs alone, from the
    // asset's frame (where an issued copy lies) and from the pose above, do not; the asset's
    // frame is kept when it explains the suspect nearly as well as the pose, the refined pose
    // when it explains it far better.
    const double full = icp_similarity(moving, closest, Points(), r.to_control_frame, o.icp, 0).rms;
    const Points& fit_points = ctx.level(ctx.fit_level).points;
    const ClosestOnSurface on_fit = [&hinted, &fit, &fit_points](const Eigen::Vector3d& q, Eigen::Index row) {
      const TriangleHit h = hinted.closest(q, row);
      const auto& t = fit.tris[static_cast<std::size_t>(h.triangle)];
      const Eigen::Vector3d p0 = fit_points.row(t[0]), p1 = fit_points.row(t[1]), p2 = fit_points.row(t[2]);
      return SurfacePoint{h.point, (p1 - p0).cross(p2 - p0).normalized()};
    };
    const IcpResult in_frame = icp_rigid_point_to_plane(moving, on_fit, Similarity(), o.icp);
    if (in_frame.rms <= kFrameTolerance * full) {
      r.to_control_frame = in_frame.transform;
    } else {
      const IcpResult refined = icp_rigid_point_to_plane(moving, on_fit, r.to_control_frame, o.icp);
      if (refined.rms < kPartialGain * full) r.to_control_frame = refined.transform;
    }
  }
  const Similarity& T = r.to_control_frame;
  const Similarity Tinv = T.inverse();
  const LevelData& level = ctx.level(ctx.fit_level);
  const SparseOperator& S = level.op.S;
  const int n = ctx.control.num_vertices();
  const int nr = static_cast<int>(S.rows());
  const double max_d = o.max_distance * ctx.diagonal;

  const Points moved = T.apply(samples);
  Points x = ctx.control.points;
  double residual = 0;
  std::vector<TriangleHit> hits(static_cast<size_t>(moved.rows()));
  // Unknowns: the control points' x, y, z (3n), coupled through the normals.
  const int n3 = 3 * n;
  Eigen::VectorXd x0(n3);
  for (int a = 0; a < 3; ++a) x0.segment(a * n, n) = ctx.control.points.col(a);
  for (int it = 0; it < std::max(1, o.fit_iterations); ++it) {
    // Pairs against the current estimate: the mark moves the surface by a fair fraction of the
    // refined edge length, so pairs with the original surface would be biased.
    const Points R = it == 0 ? level.points : apply_subdivision(level.op, x);
    const TriangleIndex current_tree(R, fit.tris);
    const TriangleIndex& surface = it == 0 ? *fit.tree : current_tree;
    // One point-to-plane row: normal . (sum_c w_c (S x)_{v_c}) = normal . target; W holds the
    // weights w_c over the refined vertices, so the rows over the control points are W S.
    std::vector<Trip> w;
    std::vector<Eigen::Vector3d> row_normals;
    std::vector<double> b;
    auto add_row = [&](std::initializer_list<std::pair<int, double>> refined, const Eigen::Vector3d& normal,
                       const Eigen::Vector3d& target) {
      const int row = static_cast<int>(b.size());
      for (auto [v, wv] : refined)
        if (wv != 0) w.emplace_back(row, v, wv);
      row_normals.push_back(normal);
      b.push_back(normal.dot(target));
    };
    int accepted = 0;
    double forward_squares = 0;
    // Suspect samples -> current refined surface (its face normal).
    for (Eigen::Index k = 0; k < moved.rows(); ++k) {
      const Eigen::Vector3d q = moved.row(k).transpose();
      TriangleHit& h = hits[static_cast<size_t>(k)];
      h = it == 0 ? surface.closest(q) : surface.closest(q, h.triangle);
      if (!(h.distance <= max_d)) continue;
      const auto& f = fit.tris[h.triangle];
      const Eigen::Vector3d p0 = R.row(f[0]), p1 = R.row(f[1]), p2 = R.row(f[2]);
      const Eigen::Vector3d normal = (p1 - p0).cross(p2 - p0).normalized();
      if (!normal.allFinite()) continue;
      add_row({{f[0], h.barycentric[0]}, {f[1], h.barycentric[1]}, {f[2], h.barycentric[2]}}, normal, q);
      forward_squares += h.distance * h.distance;
      ++accepted;
    }
    r.matched_fraction = static_cast<double>(accepted) / static_cast<double>(moved.rows());
    if (accepted < 3) throw InputError(o.source, "nothing matched the original surface after alignment");
    // Refined vertices of the current estimate -> suspect surface (the suspect's face normal),
    // where the suspect covers them: a refined vertex much farther from the suspect than the
    // suspect's samples are from the surface lies where the suspect has no surface (a crop), and
    // its pair with the crop's edge would pull the fit there.
    const double covered = std::min(max_d, kCoverage * std::sqrt(forward_squares / std::max(1, accepted)) +
                                               1e-6 * ctx.diagonal);
    const int pairs = std::min(nr, std::max(1, o.suspect_samples));
    for (int k = 0; k < pairs; ++k) {
      const int v = static_cast<int>(static_cast<long long>(k) * nr / pairs);
      const Eigen::RowVector3d pv = R.row(v);
      const TriangleHit h = suspect_tree.closest(Tinv.apply(pv).transpose());
      const Eigen::Vector3d c = T.apply(Eigen::RowVector3d(h.point.transpose())).transpose();
      const double d = (c - pv.transpose()).norm();
      if (!(d <= covered)) continue;
      const auto& f = suspect_tree.triangle(h.triangle);
      const Eigen::Vector3d s0 = suspect.points.row(f[0]), s1 = suspect.points.row(f[1]), s2 = suspect.points.row(f[2]);
      const Eigen::Vector3d normal = (T.rotation * (s1 - s0).cross(s2 - s0)).normalized();
      if (!normal.allFinite()) continue;
      add_row({{v, 1.0}}, normal, c);
    }
    const int m = static_cast<int>(b.size());
    SparseOperator W(m, nr);
    W.setFromTriplets(w.begin(), w.end());
    const SparseOperator by_row = W * S;  // m x n, the rows over the control points
    const SpMat rows = by_row;
    const SpMat rows_t = by_row.transpose();
    Points normals(m, 3);
    for (int i = 0; i < m; ++i) normals.row(i) = row_normals[static_cast<size_t>(i)].transpose();
    const std::array<SpMat, 6> grams = normal_weighted_grams(rows, rows_t, normals);
    // Tangential motion is invisible on a surface: the pull towards the original decides it.
    // Relative to the data's own weight per unknown, so the pull is a fixed fraction.
    double trace = 0;
    for (int a = 0; a < 3; ++a) trace += grams[static_cast<size_t>(a * (5 - a) / 2 + a)].diagonal().sum();
    const double lambda = o.regularization * trace / n3;
    std::vector<Trip> mt;
    for (int a = 0; a < 3; ++a)
      for (int c = a; c < 3; ++c)
        for (int j = 0; j < n; ++j)
          for (SpMat::InnerIterator e(grams[static_cast<size_t>(a * (5 - a) / 2 + c)], j); e; ++e) {
            mt.emplace_back(a * n + static_cast<int>(e.row()), c * n + j, e.value());
            if (a != c) mt.emplace_back(c * n + j, a * n + static_cast<int>(e.row()), e.value());
          }
    for (int i = 0; i < n3; ++i) mt.emplace_back(i, i, lambda);
    SpMat M(n3, n3);
    M.setFromTriplets(mt.begin(), mt.end());
    const Eigen::Map<const Eigen::VectorXd> bv(b.data(), m);
    Eigen::VectorXd rhs = lambda * x0;
    for (int a = 0; a < 3; ++a) rhs.segment(a * n, n) += rows_t * normals.col(a).cwiseProduct(bv);
    Eigen::SimplicialLDLT<SpMat> solver(M);
    if (solver.info() != Eigen::Success) throw std::runtime_error("resync: surface fit system is singular");
    const Eigen::VectorXd xv = solver.solve(rhs);
    for (int a = 0; a < 3; ++a) x.col(a) = xv.segment(a * n, n);
    // Point-to-plane residual of the solution (the distances it leaves unexplained).
    Eigen::VectorXd explained = Eigen::VectorXd::Zero(m);
    for (int a = 0; a < 3; ++a) explained += normals.col(a).cwiseProduct(rows * x.col(a));
    residual = std::sqrt((explained - bv).squaredNorm() / std::max(1, m));
  }
  r.points = x;
  r.residual_rms = residual / ctx.diagonal;
  return r;
}

}  // namespace mm::registration_detail
