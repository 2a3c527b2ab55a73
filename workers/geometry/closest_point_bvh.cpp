#include "geometry/closest_point_bvh.h"

#include "geometry/bvh_layout.h"
#include "geometry/triangle_closest_point.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace mm {
namespace {

constexpr int kLeafSize = 4;

// Two doubles in one register (GCC/Clang vector extension): a node's two child boxes are
// measured at once.

double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// A triangle as the search reads it, in leaf order; fields in the order the search reads them:
// most triangles visited are turned away by their box, read from the record's first bytes (the
// search waits on memory more than on arithmetic). Not over-aligned: std::vector's aligned
// allocations fragmented the heap (blade's protect-path peak RSS 96 -> 124 MB with these
// records and the quality tree's aligned to cache lines).
struct TriSlot {
  static constexpr int kVertices = 3;
  double lo[3], hi[3];  // bounding box
  int id;          // the caller's index
  bool regular;    // non-zero area
  bool prunable;   // plane accurate enough to skip on (not a sliver)
  double n[3], d;  // unit normal and offset (n . x = d) of the supporting plane
  double v[3][3];

  void fill(const Points& points, const std::array<int, 3>& f) {
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) v[j][k] = points(f[static_cast<size_t>(j)], k);
    const Eigen::Vector3d a(v[0][0], v[0][1], v[0][2]), b(v[1][0], v[1][1], v[1][2]), c(v[2][0], v[2][1], v[2][2]);
    const Eigen::Vector3d ab = b - a, ac = c - a, cr = ab.cross(ac);
    const double n2 = cr.squaredNorm();
    regular = n2 > 0 && std::isfinite(n2);
    // The plane distance skips a triangle only when its normal is accurate: not on slivers
    // (sine of the angle at a under 1e-4), where the cross product's rounding is large.
    prunable = regular && n2 > 1e-8 * ab.squaredNorm() * ac.squaredNorm();
    const Eigen::Vector3d nrm = regular ? Eigen::Vector3d(cr / std::sqrt(n2)) : Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) n[k] = nrm[k];
    d = nrm.dot(a);
    // Nested pairs, not std::min({...}): the same first-of-equals answer (min_element's), without
    // the initializer list's loop.
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(std::min(v[0][k], v[1][k]), v[2][k]);
      hi[k] = std::max(std::max(v[0][k], v[1][k]), v[2][k]);
    }
  }

  // Closest point (Ericson, Real-Time Collision Detection 5.1.5) with barycentric weights;
  // replaces (x, w, best2) when strictly closer than best2.
  bool project(const double* p, double& best2, double* x, double* weights) const {
    if (!regular) return false;
    // Most triangles visited are farther than the best point so far: their box (neighbours
    // beside the answer) or their plane (layers above or below it) says so cheaply.
    if (box_distance2(lo, hi, p) >= best2) return false;
    if (prunable) {
      const double dp = dot3(n, p) - d;
      if (dp * dp >= best2) return false;
    }
    const double* a = v[0];
    const double* b = v[1];
    const double* c = v[2];
    double u, s, t;  // weights of a, b, c
    closest_point_weights(a, b, c, p, u, s, t);
    double y[3], dist2 = 0;
    for (int k = 0; k < 3; ++k) {
      y[k] = u * a[k] + s * b[k] + t * c[k];
      dist2 += (y[k] - p[k]) * (y[k] - p[k]);
    }
    if (!(dist2 < best2)) return false;
    best2 = dist2;
    std::copy(y, y + 3, x);
    weights[0] = u, weights[1] = s, weights[2] = t;
    return true;
  }
};

struct SegSlot {
  static constexpr int kVertices = 2;
  double v[2][3];
  double e[3], inv_len2;
  double lo[3], hi[3];  // bounding box
  int id;
  bool regular;  // non-zero length

  void fill(const Points& points, const std::array<int, 2>& s) {
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 3; ++k) v[j][k] = points(s[static_cast<size_t>(j)], k);
    for (int k = 0; k < 3; ++k) {
      e[k] = v[1][k] - v[0][k];
      lo[k] = std::min(v[0][k], v[1][k]);
      hi[k] = std::max(v[0][k], v[1][k]);
    }
    const double len2 = dot3(e, e);
    regular = len2 > 0 && std::isfinite(len2);
    inv_len2 = regular ? 1.0 / len2 : 0.0;
  }

  // weights[0] = t with x = (1 - t) a + t b.
  bool project(const double* p, double& best2, double* x, double* weights) const {
    if (!regular) return false;
    const double ap[3] = {p[0] - v[0][0], p[1] - v[0][1], p[2] - v[0][2]};
    const double t = std::clamp(dot3(ap, e) * inv_len2, 0.0, 1.0);
    double y[3], dist2 = 0;
    for (int k = 0; k < 3; ++k) {
      y[k] = (1 - t) * v[0][k] + t * v[1][k];
      dist2 += (y[k] - p[k]) * (y[k] - p[k]);
    }
    if (!(dist2 < best2)) return false;
    best2 = dist2;
    std::copy(y, y + 3, x);
    weights[0] = t;
    return true;
  }
};

template <class Slot>
class Tree {
 public:
  static constexpr int N = Slot::kVertices;
  using Prim = std::array<int, N>;

  Tree(const Points& points, std::vector<Prim> prims) : prims_(std::move(prims)) {
    const int n = static_cast<int>(prims_.size());
    slot_of_.assign(static_cast<size_t>(n), -1);
    if (n == 0) return;
    std::vector<Eigen::Vector3d> centroid(static_cast<size_t>(n), Eigen::Vector3d::Zero());
    for (int t = 0; t < n; ++t)
      for (int j = 0; j < N; ++j)
        centroid[static_cast<size_t>(t)] += points.row(prims_[static_cast<size_t>(t)][static_cast<size_t>(j)]).transpose() / N;
    std::vector<Eigen::AlignedBox3d> box(static_cast<size_t>(n));
    for (int t = 0; t < n; ++t)
      for (int j = 0; j < N; ++j)
        box[static_cast<size_t>(t)].extend(points.row(prims_[static_cast<size_t>(t)][static_cast<size_t>(j)]).transpose().eval());
    const BvhLayout layout = binned_sah_layout(centroid, box, kLeafSize);
    const std::vector<int>& order = layout.order;
    nodes_.resize(layout.nodes.size());
    search_.resize(layout.nodes.size());
    for (size_t i = 0; i < nodes_.size(); ++i) {
      nodes_[i].first = search_[i].first = layout.nodes[i].first;
      nodes_[i].count = search_[i].count = layout.nodes[i].count;
    }
    slots_.resize(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) {
      slots_[static_cast<size_t>(k)].id = order[static_cast<size_t>(k)];
      slot_of_[static_cast<size_t>(order[static_cast<size_t>(k)])] = k;
    }
    refit(points);
  }

  bool empty() const { return regular_ == 0; }
  int slot_of(int id) const { return slot_of_[static_cast<size_t>(id)]; }

  void refit(const Points& points) {
    regular_ = 0;
    for (Slot& s : slots_) {
      s.fill(points, prims_[static_cast<size_t>(s.id)]);
      regular_ += s.regular ? 1 : 0;
    }
    // Children come after their parent: one backward pass sees every child before its parent.
    for (size_t i = nodes_.size(); i-- > 0;) {
      Node& nd = nodes_[i];
      if (nd.count > 0) {
        for (int k = 0; k < 3; ++k) {
          nd.lo[k] = std::numeric_limits<double>::infinity();
          nd.hi[k] = -std::numeric_limits<double>::infinity();
        }
        // From the slots' boxes: the same values as over their vertices one by one (min and
        // max are exact, and both keep the first of equal values in the same order).
        for (int j = nd.first; j < nd.first + nd.count; ++j)
          for (int k = 0; k < 3; ++k) {
            nd.lo[k] = std::min(nd.lo[k], slots_[static_cast<size_t>(j)].lo[k]);
            nd.hi[k] = std::max(nd.hi[k], slots_[static_cast<size_t>(j)].hi[k]);
          }
      } else {
        const Node& l = nodes_[i + 1];
        const Node& r = nodes_[static_cast<size_t>(nd.first)];
        BvhChildBoxes& cb = search_[i].children;
        for (int k = 0; k < 3; ++k) {
          nd.lo[k] = std::min(l.lo[k], r.lo[k]);
          nd.hi[k] = std::max(l.hi[k], r.hi[k]);
          cb.lo[k][0] = l.lo[k], cb.lo[k][1] = r.lo[k];
          cb.hi[k][0] = l.hi[k], cb.hi[k][1] = r.hi[k];
        }
      }
    }
  }

  // The caller's index of the closest primitive (-1 when empty), the point and the weights.
  int closest(const Eigen::Vector3d& q, int start, Eigen::Vector3d& point, double* weights) const {
    if (nodes_.empty()) return -1;
    const double p[3] = {q.x(), q.y(), q.z()};
    double best2 = std::numeric_limits<double>::infinity(), x[3] = {0, 0, 0};
    int best = -1;
    if (start >= 0 && start < static_cast<int>(slot_of_.size())) {
      const int s = slot_of_[static_cast<size_t>(start)];
      if (slots_[static_cast<size_t>(s)].project(p, best2, x, weights)) best = s;
    }
    // Depth-first, nearer child first; a subtree is skipped when its box is not closer than
    // the best point so far.
    BvhStackEntry stack[128];  // a median-split tree is at most about log2(n) deep
    int top = 0;
    stack[top++] = {0, box_distance2(nodes_[0].lo, nodes_[0].hi, p)};
    while (top > 0) {
      const BvhStackEntry e = stack[--top];
      if (e.d2 >= best2) continue;
      const SearchNode& nd = search_[static_cast<size_t>(e.node)];
      if (nd.count > 0) {
        for (int j = nd.first; j < nd.first + nd.count; ++j)
          if (slots_[static_cast<size_t>(j)].project(p, best2, x, weights)) best = j;
        continue;
      }
      const int l = e.node + 1, r = nd.first;
      double dl, dr;
      child_box_distances(nd.children, p, dl, dr);
      // The far child is usually popped later; fetching both now overlaps their misses.
      if (dr < best2) __builtin_prefetch(&search_[static_cast<size_t>(r)]);
      if (dl < best2) __builtin_prefetch(&search_[static_cast<size_t>(l)]);
      push_nearer_child_last(stack, top, l, dl, r, dr, [best2](double d) { return d < best2; });
    }
    if (best < 0) return -1;
    point = Eigen::Vector3d(x[0], x[1], x[2]);
    return slots_[static_cast<size_t>(best)].id;
  }

 private:
  struct Node {
    double lo[3], hi[3];
    int first;  // leaf: first slot; inner: index of the right child (the left one is next)
    int count;  // leaf: number of slots; inner: 0
  };
  // What the search reads of a node, in one record: its children's boxes and where they are.
  struct SearchNode {
    BvhChildBoxes children;  // inner nodes
    int first, count;        // as in Node
  };

  std::vector<Prim> prims_;
  std::vector<Node> nodes_;   // pre-order: children after their parent
  std::vector<SearchNode> search_;  // the same nodes as the search reads them
  std::vector<Slot> slots_;   // primitives in leaf order
  std::vector<int> slot_of_;  // caller's index -> slot
  int regular_ = 0;
};

}  // namespace

struct TriangleBvh::Impl {
  Tree<TriSlot> tree;
};

TriangleBvh::TriangleBvh(const Points& points, std::vector<std::array<int, 3>> triangles)
    : triangles_(std::move(triangles)), impl_(new Impl{Tree<TriSlot>(points, triangles_)}) {}
TriangleBvh::~TriangleBvh() = default;
void TriangleBvh::refit(const Points& points) { impl_->tree.refit(points); }
bool TriangleBvh::empty() const { return impl_->tree.empty(); }
int TriangleBvh::leaf_position(int t) const { return impl_->tree.slot_of(t); }

TriangleHit TriangleBvh::closest(const Eigen::Vector3d& q, int start_triangle) const {
  TriangleHit h;
  double w[3] = {1, 0, 0};
  h.triangle = impl_->tree.closest(q, start_triangle, h.point, w);
  if (h.triangle < 0) return h;
  h.barycentric = Eigen::Vector3d(w[0], w[1], w[2]);
  h.distance = (h.point - q).norm();
  return h;
}

struct SegmentBvh::Impl {
  Tree<SegSlot> tree;
};

namespace {
std::vector<std::array<int, 2>> as_arrays(const std::vector<std::pair<int, int>>& s) {
  std::vector<std::array<int, 2>> out(s.size());
  for (size_t k = 0; k < s.size(); ++k) out[k] = {s[k].first, s[k].second};
  return out;
}
}  // namespace

SegmentBvh::SegmentBvh(const Points& points, std::vector<std::pair<int, int>> segments)
    : segments_(std::move(segments)), impl_(new Impl{Tree<SegSlot>(points, as_arrays(segments_))}) {}
SegmentBvh::~SegmentBvh() = default;
void SegmentBvh::refit(const Points& points) { impl_->tree.refit(points); }
bool SegmentBvh::empty() const { return impl_->tree.empty(); }

SegmentHit SegmentBvh::closest(const Eigen::Vector3d& q, int start_segment) const {
  SegmentHit h;
  double t[1] = {0};
  h.segment = impl_->tree.closest(q, start_segment, h.point, t);
  if (h.segment < 0) return h;
  h.t = t[0];
  h.distance = (h.point - q).norm();
  return h;
}

}  // namespace mm
