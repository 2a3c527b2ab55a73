#include "registration/align_similarity.h"

#include "geometry/nearest_neighbours.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace mm {

Eigen::RowVector3d Similarity::apply(const Eigen::RowVector3d& p) const {
  return scale * p * rotation.transpose() + translation;
}

Points Similarity::apply(const Points& p) const {
  Points out = scale * (p * rotation.transpose());
  out.rowwise() += translation;
  return out;
}

Similarity Similarity::inverse() const {
  Similarity s;
  s.scale = 1.0 / scale;
  s.rotation = rotation.transpose();
  s.translation = -s.scale * translation * rotation;
  return s;
}

Similarity Similarity::after(const Similarity& first) const {
  Similarity s;
  s.scale = scale * first.scale;
  s.rotation = rotation * first.rotation;
  s.translation = scale * first.translation * rotation.transpose() + translation;
  return s;
}

Similarity fit_similarity(const Points& src, const Points& dst, const Eigen::VectorXd* weights, double fixed_scale) {
  if (src.rows() != dst.rows()) throw std::invalid_argument("fit_similarity: row counts differ");
  const Eigen::Index n = src.rows();
  Eigen::VectorXd w = weights ? *weights : Eigen::VectorXd::Ones(n);
  if (w.size() != n) throw std::invalid_argument("fit_similarity: weight count differs");
  w = w.cwiseMax(0.0);
  if ((w.array() > 0).count() < 3) throw std::invalid_argument("fit_similarity: fewer than 3 correspondences");
  const double total = w.sum();
  const Eigen::RowVector3d cs = (w.transpose() * src) / total;
  const Eigen::RowVector3d cd = (w.transpose() * dst) / total;
  Points s = src, d = dst;
  s.rowwise() -= cs;
  d.rowwise() -= cd;
  const Eigen::Matrix3d cov = (d.transpose() * w.asDiagonal() * s) / total;  // sum w d s^T
  const double var = (s.rowwise().squaredNorm().transpose() * w)(0) / total;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sign(1, 1, 1);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) sign[2] = -1;
  Similarity out;
  out.rotation = svd.matrixU() * sign.asDiagonal() * svd.matrixV().transpose();
  out.scale = fixed_scale > 0 ? fixed_scale : var > 0 ? svd.singularValues().dot(sign) / var : 1.0;
  if (!(out.scale > 0) || !std::isfinite(out.scale)) out.scale = 1.0;
  out.translation = cd - out.scale * cs * out.rotation.transpose();
  return out;
}

Similarity fit_similarity_preserving_mark(const Mesh& original, const Points& moved) {
  const Eigen::Index n = original.points.rows();
  if (moved.rows() != n) throw std::invalid_argument("fit_similarity_preserving_mark: row counts differ");
  const auto edges = unique_edges(original);
  if (edges.empty()) throw std::invalid_argument("fit_similarity_preserving_mark: mesh without edges");
  // Delta coordinates K x, one row per vertex.
  Points d0 = Points::Zero(n, 3), ds = Points::Zero(n, 3);
  for (auto [a, b] : edges) {
    const Eigen::RowVector3d e0 = original.points.row(a) - original.points.row(b);
    const Eigen::RowVector3d es = moved.row(a) - moved.row(b);
    d0.row(a) += e0, d0.row(b) -= e0;
    ds.row(a) += es, ds.row(b) -= es;
  }
  // moved ~ s' original R'^T + t': orthogonal Procrustes with scale, no translation term
  // (K 1 = 0), then inverted.
  const Eigen::Matrix3d cov = ds.transpose() * d0;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sign(1, 1, 1);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) sign[2] = -1;
  Similarity forward;
  forward.rotation = svd.matrixU() * sign.asDiagonal() * svd.matrixV().transpose();
  const double var = d0.squaredNorm();
  forward.scale = var > 0 ? svd.singularValues().dot(sign) / var : 1.0;
  if (!(forward.scale > 0) || !std::isfinite(forward.scale)) forward.scale = 1.0;
  forward.translation = moved.colwise().mean() -
                        forward.scale * original.points.colwise().mean() * forward.rotation.transpose();
  return forward.inverse();
}

namespace {

Points strided(const Points& p, int count) {
  if (count <= 0 || p.rows() <= count) return p;
  Points out(count, 3);
  for (int k = 0; k < count; ++k) out.row(k) = p.row(static_cast<Eigen::Index>(k * p.rows() / count));
  return out;
}

// Trimmed RMS and 0/1 weights keeping the (1 - trim) closest correspondences.
double trimmed(const Eigen::VectorXd& d2, double trim, Eigen::VectorXd* weights) {
  const Eigen::Index n = d2.size();
  std::vector<Eigen::Index> order(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), Eigen::Index(0));
  const Eigen::Index keep = std::max<Eigen::Index>(3, static_cast<Eigen::Index>(std::ceil((1 - trim) * n)));
  const Eigen::Index k = std::min(keep, n);
  std::nth_element(order.begin(), order.begin() + (k - 1), order.end(),
                   [&](Eigen::Index a, Eigen::Index b) { return d2[a] < d2[b] || (d2[a] == d2[b] && a < b); });
  weights->setZero(n);
  double sum = 0;
  for (Eigen::Index i = 0; i < k; ++i) {
    (*weights)[order[static_cast<size_t>(i)]] = 1;
    sum += d2[order[static_cast<size_t>(i)]];
  }
  return std::sqrt(sum / static_cast<double>(k));
}

}  // namespace

IcpResult icp_similarity(const Points& moving, const ClosestPoint& closest, const Points& fixed_samples,
                         const Similarity& start, const IcpOptions& o, int iterations) {
  if (iterations < 0) iterations = o.iterations;
  IcpResult r;
  r.transform = start;
  r.rms = std::numeric_limits<double>::infinity();
  const Eigen::Index n = moving.rows(), m = fixed_samples.rows();
  if (n < 3) return r;
  Points src(n + m, 3), dst(n + m, 3);
  Eigen::VectorXd d2(n + m), w;
  for (int it = 0; it <= iterations; ++it) {
    const Points cur = r.transform.apply(moving);
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d q = cur.row(i).transpose();
      const Eigen::Vector3d c = closest(q, i);
      src.row(i) = moving.row(i);
      dst.row(i) = c.transpose();
      d2[i] = (c - q).squaredNorm();
    }
    if (m > 0) {
      const PointTree tree(cur);
      for (Eigen::Index k = 0; k < m; ++k) {
        double dd = 0;
        const int j = tree.nearest(fixed_samples.row(k).transpose(), &dd);
        src.row(n + k) = moving.row(j);
        dst.row(n + k) = fixed_samples.row(k);
        d2[n + k] = dd;
      }
    }
    const double rms = trimmed(d2, o.trim_fraction, &w);
    const double previous = r.rms;
    r.rms = rms;
    if (it == iterations || !(rms > 0)) break;
    if (std::isfinite(previous) && std::abs(previous - rms) <= o.tolerance * std::max(previous, 1e-300)) break;
    // Fit against the original moving points so rounding does not accumulate.
    r.transform = fit_similarity(src, dst, &w, o.keep_scale ? start.scale : 0);
    r.iterations = it + 1;
  }
  return r;
}

constexpr double kSettled = 1e-6;

IcpResult icp_rigid_point_to_plane(const Points& moving, const ClosestOnSurface& closest, const Similarity& start,
                                   const IcpOptions& o) {
  IcpResult r;
  r.transform = start;
  r.rms = std::numeric_limits<double>::infinity();
  const Eigen::Index n = moving.rows();
  if (n < 3) return r;
  Points q(n, 3), normals(n, 3);
  Eigen::VectorXd d2(n), w;
  Similarity before = start;
  for (int it = 0; it <= o.iterations; ++it) {
    const Points cur = r.transform.apply(moving);
    for (Eigen::Index i = 0; i < n; ++i) {
      const SurfacePoint s = closest(cur.row(i).transpose(), i);
      q.row(i) = s.point.transpose();
      normals.row(i) = s.normal.transpose();
      d2[i] = (cur.row(i) - q.row(i)).squaredNorm();
    }
    const double rms = trimmed(d2, o.trim_fraction, &w);
    const double previous = r.rms;
    r.rms = rms;
    if (it == o.iterations || !(rms > 0)) break;
    // Settled: near its minimum the pairs' changes move the trimmed RMS up and down by about 1e-7
    // of it round after round, so a relative tolerance finer than kSettled is never met.
    if (std::isfinite(previous) && previous - rms <= std::max(o.tolerance, kSettled) * previous) {
      if (rms > previous) r.transform = before, r.rms = previous;  // the last round's step was no gain
      break;
    }
    before = r.transform;
    // p' = p + omega x (p - c) + tau about the kept points' centroid c: residual
    // n . (p - q) + omega . ((p - c) x n) + tau . n, linear in (omega, tau).
    const Eigen::RowVector3d c = (w.transpose() * cur) / w.sum();
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (Eigen::Index i = 0; i < n; ++i) {
      if (w[i] == 0) continue;
      const Eigen::Vector3d p = cur.row(i).transpose(), nv = normals.row(i).transpose();
      if (!nv.allFinite()) continue;
      Eigen::Matrix<double, 6, 1> j;
      j << (p - c.transpose()).cross(nv), nv;
      H.noalias() += j * j.transpose();
      g.noalias() += j * nv.dot(p - q.row(i).transpose());
    }
    // A direction the normals do not constrain (a flat or cylindrical suspect) stays put.
    H.diagonal().array() += 1e-12 * (H.trace() + 1e-300);
    const Eigen::Matrix<double, 6, 1> step = -H.ldlt().solve(g);
    if (!step.allFinite()) break;
    const Eigen::Vector3d omega = step.head<3>();
    const double angle = omega.norm();
    const Eigen::Matrix3d turn =
        angle > 0 ? Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
    Similarity next = r.transform;
    next.rotation = turn * r.transform.rotation;
    next.translation = (r.transform.translation - c) * turn.transpose() + c + step.tail<3>().transpose();
    r.transform = next;
    r.iterations = it + 1;
  }
  return r;
}

std::vector<Similarity> moment_starts(const Points& moving, const Points& fixed) {
  std::vector<Similarity> starts;
  starts.emplace_back();  // identity
  if (moving.rows() < 3 || fixed.rows() < 3) return starts;
  auto moments = [](const Points& p, Eigen::RowVector3d* c, Eigen::Matrix3d* axes, double* radius) {
    *c = p.colwise().mean();
    Points q = p.rowwise() - *c;
    *radius = std::sqrt(q.rowwise().squaredNorm().mean());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(q.transpose() * q / static_cast<double>(p.rows()));
    *axes = es.eigenvectors();
  };
  Eigen::RowVector3d cm, cf;
  Eigen::Matrix3d am, af;
  double rm, rf;
  moments(moving, &cm, &am, &rm);
  moments(fixed, &cf, &af, &rf);
  if (!(rm > 0) || !(rf > 0)) return starts;
  auto make = [&](const Eigen::Matrix3d& R) {
    Similarity s;
    s.scale = rf / rm;
    s.rotation = R;
    s.translation = cf - s.scale * cm * R.transpose();
    return s;
  };
  starts.push_back(make(Eigen::Matrix3d::Identity()));
  for (int signs = 0; signs < 8; ++signs) {
    Eigen::Vector3d s((signs & 1) ? -1 : 1, (signs & 2) ? -1 : 1, (signs & 4) ? -1 : 1);
    Eigen::Matrix3d R = af * s.asDiagonal() * am.transpose();
    if (R.determinant() < 0) continue;
    starts.push_back(make(R));
  }
  return starts;
}

IcpResult align_similarity(const Points& moving, const Points& moving_samples,
                           const Points& fixed_samples, const ClosestPoint& closest,
                           const IcpOptions& o) {
  const Points probe = strided(moving, o.probe_points);
  const Points fixed_probe = strided(fixed_samples, o.probe_points);
  IcpResult best;
  best.rms = std::numeric_limits<double>::infinity();
  for (const Similarity& start : moment_starts(moving_samples, fixed_samples)) {
    IcpResult r = icp_similarity(probe, closest, fixed_probe, start, o, o.probe_iterations);
    if (r.rms < best.rms) best = r;
  }
  return icp_similarity(moving, closest, fixed_samples, best.transform, o);
}

}  // namespace mm
