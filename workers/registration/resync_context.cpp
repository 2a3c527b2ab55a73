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
#include "geometry/nearest_neighbours.h"

namespace mm {

using namespace registration_detail;

namespace {

// Approximate heap bytes of what a context keeps (allocator overhead ignored), so a cache can
// hold contexts to a memory budget.
std::size_t bytes_of(const SparseOperator& m) {
  return static_cast<std::size_t>(m.data().allocatedSize()) * (sizeof(double) + sizeof(int)) +
         static_cast<std::size_t>(m.outerSize() + 1) * sizeof(int);
}
std::size_t bytes_of(const Eigen::SimplicialLDLT<SpMat>& f) {
  if (f.rows() == 0) return 0;
  const SpMat& L = f.matrixL().nestedExpression();
  // The factor, D, both permutations and the elimination tree / nonzero counts.
  return static_cast<std::size_t>(L.data().allocatedSize()) * (sizeof(double) + sizeof(int)) +
         static_cast<std::size_t>(f.rows()) * (sizeof(double) + 5 * sizeof(int));
}
std::size_t bytes_of(const Mesh& m) {
  std::size_t b = static_cast<std::size_t>(m.points.size()) * sizeof(double) +
                  m.faces.capacity() * sizeof(std::vector<int>) + m.creases.capacity() * sizeof(m.creases[0]) +
                  m.corners.capacity() * sizeof(int);
  for (const auto& f : m.faces) b += f.capacity() * sizeof(int) + 16;  // + malloc's chunk header
  return b;
}
// TriangleIndex (its copy of the triangles, a 160-byte slot per triangle, a node per two and its
// search record): about 300 bytes per triangle;
// tests/registration/test_resync_context.cpp checks the whole estimate against the heap.
constexpr std::size_t kTriangleIndexBytesPerTriangle = 300;

}  // namespace

ResyncContext::ResyncContext(const Mesh& control, int max_level, int fit_level) : impl_(std::make_unique<Impl>()) {
  if (max_level < 0 || max_level > kMaxSubdivisionLevels)
    throw std::invalid_argument("resync: max_level outside [0, " + std::to_string(kMaxSubdivisionLevels) + "]");
  if (control.num_vertices() == 0 || control.faces.empty())
    throw InputError("control polyhedron", "no vertices or no faces");
  if (!control.points.allFinite()) throw InputError("control polyhedron", "non-finite coordinates");
  Impl& m = *impl_;
  m.control = control;
  m.max_level = max_level;
  m.diagonal = diagonal_of(control.points);
  if (!(m.diagonal > 0)) throw InputError("control polyhedron", "degenerate bounding box");
  m.fit_level = std::clamp(fit_level, std::min(1, max_level), max_level);
  // Checks the topology now, as building every level here did before levels became lazy.
  m.vertex_counts = subdivision_vertex_counts(control, max_level);
  m.fixed_bytes = sizeof(Impl) + bytes_of(m.control) + m.vertex_counts.capacity() * sizeof(long long);
  m.level(0);
}

const LevelData& ResyncContext::Impl::level(int l) const {
  if (l < 0 || l > max_level)
    throw std::out_of_range("resync: level " + std::to_string(l) + " outside [0, " + std::to_string(max_level) + "]");
  LevelSlot& slot = slots[static_cast<size_t>(l)];
  std::call_once(slot.once, [&] {
    slot.data = build_level(l);
    slot.built.store(true, std::memory_order_release);
  });
  return *slot.data;
}

std::unique_ptr<LevelData> ResyncContext::Impl::build_level(int l) const {
  auto d = std::make_unique<LevelData>();
  d->op = build_subdivision(control, l);
  d->points = l == 0 ? control.points : apply_subdivision(d->op, control.points);
  if (d->points.rows() != vertex_counts[static_cast<size_t>(l)])
    throw std::logic_error("resync: level " + std::to_string(l) + " has " + std::to_string(d->points.rows()) +
                           " vertices, its count said " + std::to_string(vertex_counts[static_cast<size_t>(l)]));
  if (l > 0) {
    const SpMat S = d->op.S;
    const SpMat StS = SpMat(S.transpose()) * S;
    d->normal.compute(StS);
    if (d->normal.info() != Eigen::Success)
      throw InputError("control polyhedron", "subdivision normal equations are singular at level " + std::to_string(l));
  }
  d->tree = std::make_unique<PointTree>(d->points);
  if (l > 0) {
    const LevelData& below = level(l - 1);
    Mesh untagged = below.op.refined;
    if (!untagged.creases.empty() || !untagged.corners.empty()) {
      // One step from the level L-1 mesh as a file numbers its edge points in that file's edge
      // order, not as the level-L refinement does. The tagged step in that numbering
      // reproduces the level-L points, which gives the permutation to the level-L numbering.
      untagged.points = below.points;
      const SparseOperator tagged_step = build_subdivision(untagged, 1).S;
      untagged.creases.clear();
      untagged.corners.clear();
      const SparseOperator U = build_subdivision(untagged, 1).S;
      const Points same = tagged_step * below.points;
      const int nr = static_cast<int>(d->points.rows());
      std::vector<int> order(static_cast<size_t>(nr), -1);
      std::vector<char> taken(static_cast<size_t>(nr), 0);
      bool bijective = same.rows() == nr;
      const double tolerance = 1e-18 * diagonal * diagonal;
      for (int j = 0; j < nr && bijective; ++j) {
        double d2 = 0;
        const int k = d->tree->nearest(same.row(j).transpose(), &d2);
        bijective = k >= 0 && d2 <= tolerance && !taken[static_cast<size_t>(k)];
        if (bijective) order[static_cast<size_t>(j)] = k, taken[static_cast<size_t>(k)] = 1;
      }
      if (bijective) {
        std::vector<Trip> t;
        t.reserve(static_cast<size_t>(U.nonZeros()));
        for (int j = 0; j < nr; ++j)
          for (SparseOperator::InnerIterator it(U, j); it; ++it)
            t.emplace_back(order[static_cast<size_t>(j)], static_cast<int>(it.col()), it.value());
        d->smooth_step.resize(nr, U.cols());
        d->smooth_step.setFromTriplets(t.begin(), t.end());
        d->smooth_order = std::move(order);
        // T^T T = S_{L-1}^T (U^T U) S_{L-1}: formed at level L-1's size, never T (at L = 4 as
        // large as S_4), and in S_{L-1}'s own row-major storage, which saves two copies of it.
        const SparseOperator UtU = SparseOperator(d->smooth_step.transpose()) * d->smooth_step;
        SpMat N;
        if (l == 1) {
          N = UtU;
        } else {
          const SparseOperator G = UtU * below.op.S;
          N = below.op.S.transpose() * G;
        }
        d->smooth_normal.compute(N);
        d->has_smooth = d->smooth_normal.info() == Eigen::Success;
      }
      if (!d->has_smooth) d->smooth_step = SparseOperator(), d->smooth_order.clear();
    }
  }
  const int nv = static_cast<int>(d->points.rows());
  d->face_offsets.assign(static_cast<size_t>(nv) + 1, 0);
  for (const auto& f : d->op.refined.faces)
    for (int v : f) ++d->face_offsets[static_cast<size_t>(v) + 1];
  for (int v = 0; v < nv; ++v) d->face_offsets[v + 1] += d->face_offsets[v];
  d->face_list.assign(static_cast<size_t>(d->face_offsets.back()), 0);
  std::vector<int> fill(d->face_offsets.begin(), d->face_offsets.end() - 1);
  for (int f = 0; f < static_cast<int>(d->op.refined.faces.size()); ++f)
    for (int v : d->op.refined.faces[f]) d->face_list[fill[v]++] = f;

  std::size_t bytes = sizeof(LevelData) + bytes_of(d->op.S) + bytes_of(d->op.refined) +
                      static_cast<std::size_t>(d->points.size()) * sizeof(double) + bytes_of(d->normal) +
                      bytes_of(d->smooth_step) + d->smooth_order.capacity() * sizeof(int) +
                      bytes_of(d->smooth_normal) + d->tree->memory_bytes() +
                      (d->face_offsets.capacity() + d->face_list.capacity()) * sizeof(int);
  for (const auto& step : d->op.steps) bytes += bytes_of(step);
  built_bytes.fetch_add(bytes, std::memory_order_relaxed);
  return d;
}

const FitSurface& ResyncContext::Impl::fit() const {
  std::call_once(fit_once, [&] {
    const LevelData& at = level(fit_level);
    auto f = std::make_unique<FitSurface>();
    f->tris = triangle_list(at.op.refined);
    f->tree = std::make_unique<TriangleIndex>(at.points, f->tris);
    f->samples = sample_area(at.points, f->tris, 20000, 7);
    built_bytes.fetch_add(sizeof(FitSurface) + f->tris.capacity() * sizeof(f->tris[0]) +
                              f->tris.size() * kTriangleIndexBytesPerTriangle +
                              static_cast<std::size_t>(f->samples.size()) * sizeof(double),
                          std::memory_order_relaxed);
    fit_surface = std::move(f);
  });
  return *fit_surface;
}

ResyncContext::~ResyncContext() = default;
ResyncContext::ResyncContext(ResyncContext&&) noexcept = default;
ResyncContext& ResyncContext::operator=(ResyncContext&&) noexcept = default;
const Mesh& ResyncContext::control() const { return impl_->control; }
int ResyncContext::max_level() const { return impl_->max_level; }
int ResyncContext::fit_level() const { return impl_->fit_level; }
double ResyncContext::diagonal() const { return impl_->diagonal; }
int ResyncContext::vertex_count(int level) const {
  if (level < 0 || level > impl_->max_level)
    throw std::out_of_range("resync: level " + std::to_string(level) + " outside [0, " +
                            std::to_string(impl_->max_level) + "]");
  return static_cast<int>(impl_->vertex_counts[static_cast<size_t>(level)]);
}
const SubdivisionOperator& ResyncContext::subdivision(int level) const { return impl_->level(level).op; }
const Points& ResyncContext::refined_points(int level) const { return impl_->level(level).points; }
bool ResyncContext::level_built(int level) const {
  return level >= 0 && level <= impl_->max_level && impl_->slots[static_cast<size_t>(level)].built.load(std::memory_order_acquire);
}
void ResyncContext::build_all() const {
  for (int l = 0; l <= impl_->max_level; ++l) impl_->level(l);
  impl_->fit();
}
std::size_t ResyncContext::memory_bytes() const { return impl_->memory_bytes(); }

}  // namespace mm
