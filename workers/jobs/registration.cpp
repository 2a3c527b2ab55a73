#include "jobs/registration.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>

namespace mm::jobs {

namespace {

// Uniform grid over points for nearest-neighbour queries; cells hold about 2 points on average.
class Grid {
 public:
  explicit Grid(const Points& p) : p_(p) {
    lo_ = p.colwise().minCoeff().transpose();
    Eigen::Vector3d hi = p.colwise().maxCoeff().transpose();
    double vol = std::max(1e-12, (hi - lo_).prod());
    double side = (hi - lo_).maxCoeff();
    cell_ = std::cbrt(vol * 2.0 / std::max<Eigen::Index>(1, p.rows()));
    cell_ = std::max(cell_, side * 1e-3);
    if (!(cell_ > 0)) cell_ = 1;
    for (Eigen::Index i = 0; i < p.rows(); ++i) cells_[key(cell_of(p.row(i).transpose()))].push_back(i);
  }
  // Index of the nearest point (exact: rings grow until the best found is provably nearest).
  Eigen::Index nearest(const Eigen::Vector3d& q) const {
    Eigen::Vector3i c = cell_of(q);
    Eigen::Index best = -1;
    double best_d = std::numeric_limits<double>::infinity();
    for (int ring = 0; ring < 4096; ++ring) {
      for (int dx = -ring; dx <= ring; ++dx)
        for (int dy = -ring; dy <= ring; ++dy)
          for (int dz = -ring; dz <= ring; ++dz) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
            auto it = cells_.find(key(c + Eigen::Vector3i(dx, dy, dz)));
            if (it == cells_.end()) continue;
            for (Eigen::Index i : it->second) {
              double d = (p_.row(i).transpose() - q).squaredNorm();
              if (d < best_d) best_d = d, best = i;
            }
          }
      // Everything outside ring r is at least r * cell away.
      if (best >= 0 && std::sqrt(best_d) <= ring * cell_) break;
    }
    return best;
  }

 private:
  Eigen::Vector3i cell_of(const Eigen::Vector3d& q) const {
    Eigen::Vector3d f = ((q - lo_) / cell_).array().floor();
    f = f.cwiseMax(-1e6).cwiseMin(1e6);
    return f.cast<int>();
  }
  static std::int64_t key(const Eigen::Vector3i& c) {
    return (std::int64_t(c[0]) * 73856093) ^ (std::int64_t(c[1]) * 19349663) ^
           (std::int64_t(c[2]) * 83492791);
  }
  const Points& p_;
  Eigen::Vector3d lo_;
  double cell_ = 1;
  std::unordered_map<std::int64_t, std::vector<Eigen::Index>> cells_;
};

// Similarity transform mapping src rows onto dst rows (least squares), applied to src.
Points align(const Points& src, const Points& dst) {
  Eigen::Matrix<double, 3, Eigen::Dynamic> s = src.transpose();
  Eigen::Matrix<double, 3, Eigen::Dynamic> d = dst.transpose();
  Eigen::Matrix4d t = Eigen::umeyama(s, d, true);
  Points out(src.rows(), 3);
  for (Eigen::Index i = 0; i < src.rows(); ++i)
    out.row(i) = (t.topLeftCorner<3, 3>() * src.row(i).transpose() + t.topRightCorner<3, 1>()).transpose();
  return out;
}

double rms(const Points& a, const Points& b) {
  return std::sqrt((a - b).rowwise().squaredNorm().mean());
}

}  // namespace

Registration register_suspect(const PreparedAsset& asset, const Mesh& suspect) {
  const Mesh& control = asset.control;
  Registration r;
  const auto n = control.points.rows();
  if (suspect.points.rows() == 0 || n == 0) {
    r.points = Points::Zero(n, 3);
    r.method = "none";
    r.rms = std::numeric_limits<double>::infinity();
    return r;
  }
  if (suspect.points.rows() == n && suspect.faces == control.faces) {
    r.method = "identity";
    r.points = align(suspect.points, control.points);
    r.rms = rms(r.points, control.points);
    r.matched_fraction = 1.0;
    return r;
  }
  r.method = "nearest-neighbour";
  // Start from bounding-box normalisation, then iterate correspondence + similarity alignment.
  Points moved = suspect.points;
  try {
    apply(unit_box_normalization(moved), moved);
  } catch (const std::invalid_argument&) {
    r.points = Points::Zero(n, 3);
    r.rms = std::numeric_limits<double>::infinity();
    return r;
  }
  Points matched(n, 3);
  std::vector<Eigen::Index> idx(static_cast<std::size_t>(n));
  for (int iter = 0; iter < 4; ++iter) {
    Grid grid(moved);
    for (Eigen::Index i = 0; i < n; ++i) {
      idx[static_cast<std::size_t>(i)] = grid.nearest(control.points.row(i).transpose());
      matched.row(i) = suspect.points.row(idx[static_cast<std::size_t>(i)]);
    }
    Points aligned = align(matched, control.points);
    // Move the whole suspect by the same transform for the next round of correspondences.
    Eigen::Matrix4d t = Eigen::umeyama(Eigen::Matrix<double, 3, Eigen::Dynamic>(matched.transpose()),
                                       Eigen::Matrix<double, 3, Eigen::Dynamic>(control.points.transpose()),
                                       true);
    for (Eigen::Index i = 0; i < suspect.points.rows(); ++i)
      moved.row(i) = (t.topLeftCorner<3, 3>() * suspect.points.row(i).transpose() + t.topRightCorner<3, 1>()).transpose();
    r.points = aligned;
  }
  r.rms = rms(r.points, control.points);
  std::unordered_set<Eigen::Index> distinct(idx.begin(), idx.end());
  r.matched_fraction = static_cast<double>(distinct.size()) / static_cast<double>(n);
  return r;
}

}  // namespace mm::jobs
