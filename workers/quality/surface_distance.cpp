#include "quality/surface_distance.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "geometry/triangle_distance_tree.h"
#include "subdivision/decompress.h"

namespace mm {
namespace {

struct Tri {
  Eigen::Vector3d a, b, c;
  double area;
  std::array<int, 3> corners;  // vertex indices of a, b, c
};

// Fan triangles of positive area; degenerate ones add nothing to a surface and would only
// trouble the closest-point queries.
std::vector<Tri> triangles(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  if (!mesh.points.allFinite()) throw InputError("quality", "mesh has non-finite coordinates");
  std::vector<Tri> out;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    for (int v : face)
      if (v < 0 || v >= n)
        throw InputError("quality", "face " + std::to_string(f) + " has a vertex index out of range");
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      Tri t{mesh.points.row(face[0]).transpose(), mesh.points.row(face[k]).transpose(),
            mesh.points.row(face[k + 1]).transpose(), 0, {face[0], face[k], face[k + 1]}};
      t.area = 0.5 * (t.b - t.a).cross(t.c - t.a).norm();
      if (t.area > 0) out.push_back(t);
    }
  }
  if (out.empty()) throw InputError("quality", "mesh has no face of positive area");
  return out;
}


double diagonal_of(const Mesh& mesh) {
  if (mesh.num_vertices() == 0) return 0;
  return (mesh.points.colwise().maxCoeff() - mesh.points.colwise().minCoeff()).norm();
}

// splitmix64's output function: a well-mixed 64-bit value from any 64-bit input.
std::uint64_t mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// sample_surface on the mesh's triangles (triangles(mesh)), for a caller that has them already.
// Each triangle's samples are drawn from a stream seeded by its own corners and the seed, so the
// samples are the same set whatever the order of the faces, the numbering of the vertices or the
// corner a face starts at: a stream that reorders a surface measures as the surface itself.
std::vector<Eigen::Vector3d> sample_triangles(const std::vector<Tri>& tris, const Mesh& mesh, int samples,
                                              std::uint64_t seed, bool include_vertices) {
  std::vector<Eigen::Vector3d> out;
  const std::size_t count = static_cast<std::size_t>(std::max(samples, 0));
  out.reserve(count + count / 16 + (include_vertices ? mesh.num_vertices() : 0));
  // Corners are known by their coordinates on a grid of 2^-32 of the surface's extent: a
  // surface decoded in another order, whose coordinates differ in their last bits, still orders
  // each triangle's corners alike and draws the same samples.
  Eigen::AlignedBox3d box;
  for (const Tri& t : tris) box.extend(t.a), box.extend(t.b), box.extend(t.c);
  const double extent = std::max(box.sizes().maxCoeff(), std::numeric_limits<double>::min());
  const double grid = std::ldexp(1.0, std::ilogb(extent) - 32);
  using Key = std::array<long long, 3>;
  const auto key_of = [grid](const Eigen::Vector3d& p) {
    return Key{std::llround(p[0] / grid), std::llround(p[1] / grid), std::llround(p[2] / grid)};
  };
  std::vector<std::array<Eigen::Vector3d, 3>> corners(tris.size());
  std::vector<std::array<Key, 3>> keys(tris.size());
  std::vector<double> areas(tris.size());
  for (std::size_t i = 0; i < tris.size(); ++i) {
    // The corners in the order of their keys: the same triangle whichever corner a face names first.
    std::array<std::pair<Key, Eigen::Vector3d>, 3> c{{{key_of(tris[i].a), tris[i].a},
                                                       {key_of(tris[i].b), tris[i].b},
                                                       {key_of(tris[i].c), tris[i].c}}};
    std::sort(c.begin(), c.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    for (int k = 0; k < 3; ++k) corners[i][k] = c[k].second, keys[i][k] = c[k].first;
    areas[i] = 0.5 * (corners[i][1] - corners[i][0]).cross(corners[i][2] - corners[i][0]).norm();
  }
  // The total in ascending order: the same sum for any order of the faces.
  std::vector<double> sorted = areas;
  std::sort(sorted.begin(), sorted.end());
  double total = 0;
  for (double a : sorted) total += a;
  for (std::size_t i = 0; i < tris.size() && count > 0; ++i) {
    const auto& c = corners[i];
    std::uint64_t state = mix64(seed);
    for (const Key& k : keys[i])
      for (long long x : k) state = mix64(state ^ static_cast<std::uint64_t>(x));
    const auto next = [&state] {
      state = mix64(state);
      return static_cast<double>(state >> 11) * 0x1.0p-53;
    };
    // Its area's share of the samples, rounded up or down at random: the count is `samples` on
    // average, and each triangle's is within one of its share.
    const double share = areas[i] / total * static_cast<double>(count);
    const auto n = static_cast<std::size_t>(std::floor(share + next()));
    for (std::size_t k = 0; k < n; ++k) {
      double r1 = next(), r2 = next();
      if (r1 + r2 > 1) {
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      out.push_back(c[0] + r1 * (c[1] - c[0]) + r2 * (c[2] - c[0]));
    }
  }
  if (include_vertices) {
    std::vector<char> used(mesh.num_vertices(), 0);
    for (const auto& f : mesh.faces)
      for (int v : f) used[v] = 1;
    for (int v = 0; v < mesh.num_vertices(); ++v)
      if (used[v]) out.push_back(mesh.points.row(v).transpose());
  }
  return out;
}

}  // namespace

std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, int samples, std::uint64_t seed,
                                            bool include_vertices) {
  return sample_triangles(triangles(mesh), mesh, samples, seed, include_vertices);
}

// The samples along a Morton (Z-order) curve through their bounding box, ties by index: neighbours
// on the curve lie near each other, so each query starts near its answer. Area samples come
// triangle by triangle, but within a large triangle they lie anywhere (abc7's part: 14 % of the
// tolerance checks were answered by the previous sample's triangle in index order).
std::vector<int> spatial_order(const std::vector<Eigen::Vector3d>& points) {
  Eigen::AlignedBox3d box;
  for (const auto& p : points) box.extend(p);
  const Eigen::Vector3d lo = box.min(), size = box.sizes().cwiseMax(std::numeric_limits<double>::min());
  // 21 bits per axis, interleaved.
  const auto spread = [](std::uint64_t x) {
    x &= 0x1fffff;
    x = (x | x << 32) & 0x1f00000000ffffull;
    x = (x | x << 16) & 0x1f0000ff0000ffull;
    x = (x | x << 8) & 0x100f00f00f00f00full;
    x = (x | x << 4) & 0x10c30c30c30c30c3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
  };
  std::vector<std::pair<std::uint64_t, int>> keyed(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::uint64_t code = 0;
    for (int k = 0; k < 3; ++k) {
      const double t = std::clamp((points[i][k] - lo[k]) / size[k], 0.0, 1.0);
      code |= spread(static_cast<std::uint64_t>(t * 2097151.0)) << k;
    }
    keyed[i] = {code, static_cast<int>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> order(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) order[i] = keyed[i].second;
  return order;
}

namespace {

// The closest-point tree of a surface's triangles (triangles(mesh)), on `layout` if given.
std::unique_ptr<TriangleDistanceTree> tree_of(const std::vector<Tri>& tris,
                                              std::shared_ptr<const BvhLayout> layout = nullptr) {
  std::vector<std::array<Eigen::Vector3d, 3>> corners;
  corners.reserve(tris.size());
  for (const Tri& t : tris) corners.push_back({t.a, t.b, t.c});
  return std::make_unique<TriangleDistanceTree>(corners, std::move(layout));
}

// How many surfaces measured against a part have their trees' layouts remembered
// (MeasuredSurface::Impl::tree_for): the stream search measures two or three polyhedra in turn.
constexpr std::size_t kRememberedLayouts = 4;

std::vector<Eigen::Vector3d> samples_of(const std::vector<Tri>& tris, const Mesh& mesh, const SamplingParams& params) {
  std::vector<Eigen::Vector3d> points = sample_triangles(tris, mesh, params.samples, params.seed, params.include_vertices);
  if (points.empty()) throw InputError("quality", "no samples: give samples > 0 or include vertices");
  return points;
}

// A different seed for the other direction keeps the two sample sets independent.
SamplingParams other_direction(const SamplingParams& params) {
  SamplingParams back = params;
  back.seed = params.seed ^ 0x9E3779B97F4A7C15ull;
  return back;
}

// One direction of a measurement: the samples of one surface and the tree of the other. Each
// sample's distance does not depend on the order the samples are measured in (the tree's hint
// only speeds a query up), and the statistics are summed in sample order, so a measurement in
// passes gives the numbers of one in sample order.
class Direction {
 public:
  // `order`, when given, is the order the last pass queries the samples in (spatial_order).
  Direction(const std::vector<Eigen::Vector3d>& points, const TriangleDistanceTree& tree,
            const std::vector<int>* order = nullptr)
      : tree_(tree), points_(points), order_(order) {}
  // Measures samples 0, stride, 2 stride, ... but those a pass with stride `coarser` measured
  // (0: none). False as soon as one lies farther than limit * diagonal (exactly as
  // hausdorff_relative() compares: distance / diagonal).
  bool measure(std::size_t stride, std::size_t coarser, double limit, double diagonal) {
    squared_.resize(points_.size(), 0.0);
    // Each query starts from the previous answer, which lies near when the samples do.
    return each_sample(stride, coarser, [&](std::size_t i) {
      squared_[i] = tree_.squared_distance(points_[i], hint_);
      return !(std::sqrt(squared_[i]) / diagonal > limit);
    });
  }
  // The same decision as measure (false: a sample farther than limit * diagonal), but a sample
  // is measured only when no triangle lies certainly within the limit
  // (TriangleDistanceTree::within): the numbers are not needed, only the answer.
  bool within(std::size_t stride, std::size_t coarser, double limit, double diagonal) {
    // A hair inside the limit, so that distances within rounding of it are measured and compared
    // exactly as measure() compares them.
    const double r = limit * diagonal * (1 - 1e-12);
    return each_sample(stride, coarser, [&](std::size_t i) {
      return tree_.within(points_[i], r, hint_) ||
             !(std::sqrt(tree_.squared_distance(points_[i], hint_)) / diagonal > limit);
    });
  }
  OneSidedDistance stats() const {
    OneSidedDistance d;
    double sum = 0, sum_sq = 0;
    for (double sq : squared_) {
      const double dist = std::sqrt(sq);
      d.max = std::max(d.max, dist);
      sum += dist;
      sum_sq += sq;
    }
    d.samples = points_.size();
    d.mean = sum / static_cast<double>(points_.size());
    d.rms = std::sqrt(sum_sq / static_cast<double>(points_.size()));
    return d;
  }

 private:
  // Calls f on samples 0, stride, 2 stride, ... but those a pass with stride `coarser` had (0:
  // none) until it returns false. Which sample comes first changes no answer (each sample's
  // distance does not depend on it, and the statistics are summed in index order), only how
  // near each query's start is: the last pass (stride 1, three quarters of the samples) goes in
  // `order_` when there is one.
  template <class F>
  bool each_sample(std::size_t stride, std::size_t coarser, F f) {
    const auto skip = [coarser](std::size_t i) { return coarser > 0 && i % coarser == 0; };
    if (stride == 1 && order_) {
      for (int i : *order_)
        if (!skip(static_cast<std::size_t>(i)) && !f(static_cast<std::size_t>(i))) return false;
      return true;
    }
    for (std::size_t i = 0; i < points_.size(); i += stride)
      if (!skip(i) && !f(i)) return false;
    return true;
  }

  const TriangleDistanceTree& tree_;
  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<int>* order_;
  std::vector<double> squared_;  // sized by the first measure()
  int hint_ = -1;
};

// Strides of the passes of a measurement with a limit (a surface far off shows in the first),
// and of one without.
const std::vector<std::size_t> kPasses{64, 16, 4, 1}, kWhole{1};

}  // namespace

struct MeasuredSurface::Impl {
  Mesh mesh;
  SamplingParams params;
  double diagonal = 0;
  // Built by the first measurement (std::call_once: a failed build throws and leaves it for
  // the next to try).
  mutable std::once_flag built;
  mutable std::unique_ptr<TriangleDistanceTree> tree;
  mutable std::vector<Eigen::Vector3d> samples;
  mutable std::vector<int> order;  // spatial_order(samples)
  // Layouts of the trees of the last surfaces measured against this one, by their triangles'
  // vertex indices, most recent first: candidates of one control polyhedron (its streams at
  // several grids, snapped, descended) decode to moves of the same refined triangles, and a
  // tree on a remembered layout skips the split (TriangleDistanceTree's answers do not depend
  // on it).
  mutable std::mutex layouts_mutex;
  mutable std::deque<std::pair<std::vector<std::array<int, 3>>, std::shared_ptr<const BvhLayout>>> layouts;
  std::unique_ptr<TriangleDistanceTree> tree_for(const std::vector<Tri>& tris) const {
    std::vector<std::array<int, 3>> key(tris.size());
    for (std::size_t i = 0; i < tris.size(); ++i) key[i] = tris[i].corners;
    std::shared_ptr<const BvhLayout> known;
    {
      const std::lock_guard<std::mutex> lock(layouts_mutex);
      for (const auto& [k, layout] : layouts)
        if (k == key) {
          known = layout;
          break;
        }
    }
    auto made = tree_of(tris, known);
    if (!known) {
      const std::lock_guard<std::mutex> lock(layouts_mutex);
      layouts.emplace_front(std::move(key), made->layout());
      if (layouts.size() > kRememberedLayouts) layouts.pop_back();
    }
    return made;
  }
  void build() const {
    std::call_once(built, [this] {
      const std::vector<Tri> tris = triangles(mesh);
      auto t = tree_of(tris);
      samples = samples_of(tris, mesh, params);
      order = spatial_order(samples);
      tree = std::move(t);
    });
  }
};

MeasuredSurface::MeasuredSurface(const Mesh& mesh, const SamplingParams& params) {
  auto im = std::make_shared<Impl>();
  im->mesh = mesh;
  im->params = params;
  im->diagonal = diagonal_of(mesh);
  impl_ = std::move(im);
}

MeasuredSurface::~MeasuredSurface() = default;

const Mesh& MeasuredSurface::mesh() const { return impl_->mesh; }
const SamplingParams& MeasuredSurface::params() const { return impl_->params; }
double MeasuredSurface::diagonal() const { return impl_->diagonal; }

const TriangleDistanceTree& MeasuredSurface::tree() const {
  impl_->build();
  return *impl_->tree;
}

const std::vector<Eigen::Vector3d>& MeasuredSurface::samples() const {
  impl_->build();
  return impl_->samples;
}

const std::vector<int>& MeasuredSurface::sample_order() const {
  impl_->build();
  return impl_->order;
}

namespace {

// A surface b against a measured part: both directions of a measurement, b's tree and samples
// made from b's triangles (triangles(b), computed by the caller: they are checked before the
// part is built, as when the part's tree was built per measurement). in_passes runs the
// part's side and b's side of each pass in turn, until one fails. b's tree and samples are made
// when a direction first needs them: a candidate turned away by the part's samples in the first
// pass needs none of b's samples.
struct Against {
  Against(const MeasuredSurface& a, const Mesh& b, std::vector<Tri> b_tris) : a_(a), b_(b), b_tris_(std::move(b_tris)) {}
  template <class Pass>
  bool in_passes(const std::vector<std::size_t>& strides, Pass pass) {
    std::size_t coarser = 0;
    for (std::size_t stride : strides) {
      if (!pass(ab(), stride, coarser) || !pass(ba(), stride, coarser)) return false;
      coarser = stride;
    }
    return true;
  }
  // The part's samples to b.
  Direction& ab() {
    if (!ab_) {
      b_tree_ = a_.impl().tree_for(b_tris_);
      ab_.emplace(a_.samples(), *b_tree_, &a_.sample_order());
    }
    return *ab_;
  }
  // b's samples to the part.
  Direction& ba() {
    if (!ba_) {
      b_samples_ = samples_of(b_tris_, b_, other_direction(a_.params()));
      ba_.emplace(b_samples_, a_.tree());
    }
    return *ba_;
  }

 private:
  const MeasuredSurface& a_;
  const Mesh& b_;
  const std::vector<Tri> b_tris_;
  std::unique_ptr<TriangleDistanceTree> b_tree_;
  std::vector<Eigen::Vector3d> b_samples_;
  std::optional<Direction> ab_, ba_;
};

}  // namespace

OneSidedDistance one_sided_distance(const Mesh& from, const Mesh& to, const SamplingParams& params) {
  const auto tree = tree_of(triangles(to));
  const std::vector<Eigen::Vector3d> points = samples_of(triangles(from), from, params);
  Direction d(points, *tree);
  d.measure(1, 0, std::numeric_limits<double>::infinity(), 1.0);
  return d.stats();
}

SurfaceDistance decoded_distance(const Mesh& part, const Mesh& control, int levels, const SamplingParams& params) {
  return surface_distance(part, decompress_to_level(control, levels), params);
}

SurfaceDistance decoded_distance(const MeasuredSurface& part, const Mesh& control, int levels) {
  return *surface_distance_within(part, decompress_to_level(control, levels), std::numeric_limits<double>::infinity());
}

std::optional<SurfaceDistance> decoded_distance_within(const Mesh& part, const Mesh& control, int levels, double limit,
                                                       const SamplingParams& params) {
  return surface_distance_within(part, decompress_to_level(control, levels), limit, params);
}

std::optional<SurfaceDistance> decoded_distance_within(const MeasuredSurface& part, const Mesh& control, int levels,
                                                       double limit) {
  return surface_distance_within(part, decompress_to_level(control, levels), limit);
}

bool decoded_within(const MeasuredSurface& part, const Mesh& control, int levels, double limit) {
  return surface_within(part, decompress_to_level(control, levels), limit);
}

SurfaceDistance surface_distance(const Mesh& a, const Mesh& b, const SamplingParams& params) {
  return *surface_distance_within(a, b, std::numeric_limits<double>::infinity(), params);
}

std::optional<SurfaceDistance> surface_distance_within(const Mesh& a, const Mesh& b, double limit,
                                                       const SamplingParams& params) {
  return surface_distance_within(MeasuredSurface(a, params), b, limit);
}

bool surface_within(const MeasuredSurface& measured, const Mesh& b, double limit) {
  Against m(measured, b, triangles(b));
  // Everything is within an infinite limit; both sides are still made, so bad input fails here
  // as in a measurement.
  if (std::isinf(limit)) return m.ab(), m.ba(), true;
  return m.in_passes(kPasses, [&](Direction& d, std::size_t stride, std::size_t coarser) {
    return d.within(stride, coarser, limit, measured.diagonal());
  });
}

std::optional<SurfaceDistance> surface_distance_within(const MeasuredSurface& measured, const Mesh& b, double limit) {
  SurfaceDistance s;
  s.diagonal = measured.diagonal();
  Against m(measured, b, triangles(b));
  if (!m.in_passes(std::isinf(limit) ? kWhole : kPasses,
                   [&](Direction& d, std::size_t stride, std::size_t coarser) {
                     return d.measure(stride, coarser, limit, s.diagonal);
                   }))
    return std::nullopt;
  s.a_to_b = m.ab().stats();
  s.b_to_a = m.ba().stats();
  s.hausdorff = std::max(s.a_to_b.max, s.b_to_a.max);
  s.rms = std::max(s.a_to_b.rms, s.b_to_a.rms);
  s.mean = std::max(s.a_to_b.mean, s.b_to_a.mean);
  return s;
}

}  // namespace mm
