// Internal to workers/registration: what a ResyncContext holds (its levels, built on first use,
// and the remeshed suspects' fit surface), shared by resync_context.cpp, which builds it, and
// resynchronize.cpp, which reads it. Not part of the library's interface.
#pragma once
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <array>
#include <atomic>
#include <memory>
#include <mutex>
#include <random>
#include <vector>

#include "geometry/closest_point.h"
#include "geometry/nearest_neighbours.h"
#include "registration/resynchronize.h"

namespace mm {

namespace registration_detail {

using SpMat = Eigen::SparseMatrix<double>;  // column-major for the factorisation
using Trip = Eigen::Triplet<double>;

inline double uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

inline double diagonal_of(const Points& p) {
  if (p.rows() == 0) return 0;
  return (p.colwise().maxCoeff() - p.colwise().minCoeff()).norm();
}

// Area-weighted points on a triangle soup, seeded.
inline Points sample_area(const Points& points, const std::vector<std::array<int, 3>>& tris, int count,
                   std::uint64_t seed) {
  std::vector<double> cumulative;
  cumulative.reserve(tris.size());
  double total = 0;
  for (const auto& t : tris) {
    const Eigen::Vector3d a = points.row(t[0]), b = points.row(t[1]), c = points.row(t[2]);
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative.push_back(total);
  }
  if (!(total > 0) || count <= 0) return Points(0, 3);
  Points out(count, 3);
  std::mt19937_64 rng(seed);
  for (int k = 0; k < count; ++k) {
    const double r = uniform(rng) * total;
    const size_t t = std::min(cumulative.size() - 1,
                              static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), r) -
                                                  cumulative.begin()));
    double u = uniform(rng), v = uniform(rng);
    if (u + v > 1) u = 1 - u, v = 1 - v;
    const auto& f = tris[t];
    const Eigen::RowVector3d a = points.row(f[0]), b = points.row(f[1]), c = points.row(f[2]);
    out.row(k) = a + u * (b - a) + v * (c - a);
  }
  return out;
}

inline Points strided(const Points& p, int count) {
  if (count <= 0 || p.rows() <= count) return p;
  Points out(count, 3);
  for (int k = 0; k < count; ++k) out.row(k) = p.row(static_cast<Eigen::Index>(static_cast<long long>(k) * p.rows() / count));
  return out;
}

inline Points stack(const Points& a, const Points& b) {
  Points out(a.rows() + b.rows(), 3);
  out << a, b;
  return out;
}


}  // namespace registration_detail

using registration_detail::SpMat;

struct LevelData {
  SubdivisionOperator op;  // level 0: the identity on the control
  Points points;           // original refined positions
  Eigen::SimplicialLDLT<SpMat> normal;  // S^T S (levels >= 1)
  // Re-subdivided leak (levels >= 1, only when the level below carries creases or corners): the
  // level L-1 original refined once more by the plain scheme, as subdivide() does on a decoded
  // file, which carries no tags: T = smooth_step * S_{L-1}. Same topology and numbering as level
  // L, different rows near creases. T itself is never stored (at L = 4 it is as large as S_4).
  bool has_smooth = false;
  SparseOperator smooth_step;                // level L-1 -> L, creases and corners ignored
  std::vector<int> smooth_order;  // refined vertex in a file's one-step numbering -> level-L index
  Eigen::SimplicialLDLT<SpMat> smooth_normal;  // T^T T
  std::unique_ptr<PointTree> tree;
  std::vector<int> face_offsets, face_list;  // vertex -> incident refined faces
};

// The remeshed suspects' target: the original refined surface at fit_level.
struct FitSurface {
  std::vector<std::array<int, 3>> tris;  // triangles of the refined original at fit_level
  std::unique_ptr<TriangleIndex> tree;
  Points samples;  // area-weighted samples of that surface (moments, reverse ICP pairs)
};

// Levels and the fit surface are built on first use: a suspect needs the level its vertex count
// names (and the one below, for the re-subdivided hypothesis) or the fit surface, rarely all of
// them, and level 4 alone is about three quarters of everything. Each is built once (call_once;
// a build that throws is retried by the next caller) and never changes afterwards, so readers
// need no lock once they hold the reference.
struct ResyncContext::Impl {
  Mesh control;
  int max_level = 0, fit_level = 0;
  double diagonal = 0;
  std::vector<long long> vertex_counts;  // per level, from the topology alone

  const LevelData& level(int l) const;
  const FitSurface& fit() const;
  std::size_t memory_bytes() const { return fixed_bytes + built_bytes.load(std::memory_order_relaxed); }

 private:
  friend class ResyncContext;
  struct LevelSlot {
    std::once_flag once;
    std::unique_ptr<LevelData> data;
    std::atomic<bool> built{false};  // for level_built(), which must not wait for a build
  };
  mutable std::array<LevelSlot, kMaxSubdivisionLevels + 1> slots;
  mutable std::once_flag fit_once;
  mutable std::unique_ptr<FitSurface> fit_surface;
  std::size_t fixed_bytes = 0;
  mutable std::atomic<std::size_t> built_bytes{0};

  std::unique_ptr<LevelData> build_level(int l) const;
};

namespace registration_detail {
// A remeshed suspect (no vertex correspondence): the control points fitted to its surface by
// closest points both ways against the refined original at the context's fit level.
Resynchronized surface_fit(const ResyncContext::Impl& ctx, const Mesh& suspect, const ResyncOptions& o);
}  // namespace registration_detail

}  // namespace mm
