#include "geometry/triangle_distance_tree.h"

#include "geometry/bvh_layout.h"
#include "geometry/triangle_closest_point.h"

#include <CGAL/Simple_cartesian.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace mm {
namespace {

using K = CGAL::Simple_cartesian<double>;
constexpr int kLeafSize = 4;

// Fields in the order a search reads them: most triangles visited are turned away by their box
// or plane, the record's first bytes (the search waits on memory more than on arithmetic; not
// over-aligned, see closest_point_bvh.cpp).
struct Tri {
  double lo[3], hi[3];
  double n[3], d;  // unit normal and offset of the plane, when `prunable`
  bool prunable;   // not a sliver: the plane distance is accurate enough to skip on
  double v[3][3];  // the corners again, as plain doubles for ericson2()
  K::Triangle_3 t;
};

// A node as the search reads it, in one record.
struct Node {
  BvhChildBoxes children;  // inner nodes: the children's boxes
  int first;  // leaf: first triangle (leaf order); inner: index of the right child (left is next)
  int count;  // leaf: number of triangles; inner: 0
};


// Squared distance from p to the triangle a b c by Ericson's closest point (Real-Time Collision
// Detection 5.1.5): other arithmetic than CGAL's projection, the same distance up to rounding,
// for a third of the instructions. Only decides which triangles CGAL measures.
double ericson2(const double* a, const double* b, const double* c, const double* p) {
  double u, s, t;  // weights of a, b, c
  closest_point_weights(a, b, c, p, u, s, t);
  double d2sum = 0;
  for (int k = 0; k < 3; ++k) {
    const double y = u * a[k] + s * b[k] + t * c[k] - p[k];
    d2sum += y * y;
  }
  return d2sum;
}

}  // namespace

struct TriangleDistanceTree::Impl {
  std::vector<Tri> tris;     // leaf order
  std::vector<Node> nodes;   // pre-order
  // The split the nodes were made from; its order gives, per leaf position, the triangle's index
  // in the constructor's list.
  std::shared_ptr<const BvhLayout> layout;
  double root_lo[3], root_hi[3];
  double eps = 0;            // distance slack of the skip tests (see closest())

  // Boxes bottom-up (children come after their parent in pre-order); returns the node's box.
  Eigen::AlignedBox3d fill_boxes(int node, const std::vector<Eigen::AlignedBox3d>& box, const std::vector<int>& order) {
    const Node& nd = nodes[static_cast<size_t>(node)];
    Eigen::AlignedBox3d out;
    if (nd.count > 0) {
      for (int k = nd.first; k < nd.first + nd.count; ++k) out.extend(box[static_cast<size_t>(order[static_cast<size_t>(k)])]);
      return out;
    }
    const Eigen::AlignedBox3d l = fill_boxes(node + 1, box, order), r = fill_boxes(nd.first, box, order);
    BvhChildBoxes& cb = nodes[static_cast<size_t>(node)].children;
    for (int k = 0; k < 3; ++k) {
      cb.lo[k][0] = l.min()[k], cb.lo[k][1] = r.min()[k];
      cb.hi[k][0] = l.max()[k], cb.hi[k][1] = r.max()[k];
    }
    return l.merged(r);
  }
};

TriangleDistanceTree::TriangleDistanceTree(const std::vector<std::array<Eigen::Vector3d, 3>>& triangles)
    : TriangleDistanceTree(triangles, nullptr) {}

TriangleDistanceTree::TriangleDistanceTree(const std::vector<std::array<Eigen::Vector3d, 3>>& triangles,
                                           std::shared_ptr<const BvhLayout> given)
    : impl_(std::make_unique<Impl>()) {
  const int n = static_cast<int>(triangles.size());
  if (n == 0) throw std::invalid_argument("TriangleDistanceTree: no triangles");
  if (given && given->order.size() != triangles.size())
    throw std::invalid_argument("TriangleDistanceTree: a layout for " + std::to_string(given->order.size()) +
                                " triangles given " + std::to_string(n));
  std::vector<Eigen::AlignedBox3d> box(static_cast<size_t>(n));
  Eigen::AlignedBox3d all;
  for (int t = 0; t < n; ++t) {
    for (const auto& v : triangles[static_cast<size_t>(t)]) box[static_cast<size_t>(t)].extend(v);
    all.extend(box[static_cast<size_t>(t)]);
  }
  if (!given) {
    std::vector<Eigen::Vector3d> centroid(static_cast<size_t>(n));
    for (int t = 0; t < n; ++t) {
      const auto& tr = triangles[static_cast<size_t>(t)];
      centroid[static_cast<size_t>(t)] = (tr[0] + tr[1] + tr[2]) / 3;
    }
    given = std::make_shared<const BvhLayout>(binned_sah_layout(centroid, box, kLeafSize));
  }
  impl_->layout = given;
  const BvhLayout& layout = *given;
  const std::vector<int>& order = layout.order;
  impl_->nodes.reserve(layout.nodes.size());
  for (const auto& nd : layout.nodes) {
    impl_->nodes.emplace_back();
    impl_->nodes.back().first = nd.first;
    impl_->nodes.back().count = nd.count;
  }
  const Eigen::AlignedBox3d root = impl_->fill_boxes(0, box, order);
  for (int k = 0; k < 3; ++k) impl_->root_lo[k] = root.min()[k], impl_->root_hi[k] = root.max()[k];
  // Rounding slack: a projection CGAL computes may lie a few ulps outside its triangle's box or
  // plane; the skip tests allow a distance far above that, so no candidate that could set the
  // minimum is skipped (the answer is the minimum over all triangles, as CGAL's).
  const double magnitude = std::max(all.max().cwiseAbs().maxCoeff(), all.min().cwiseAbs().maxCoeff());
  impl_->eps = 1e-9 * std::max({(all.max() - all.min()).norm(), magnitude, std::numeric_limits<double>::min()});
  impl_->tris.resize(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) {
    const auto& tr = triangles[static_cast<size_t>(order[static_cast<size_t>(k)])];
    Tri& s = impl_->tris[static_cast<size_t>(k)];
    s.t = K::Triangle_3(K::Point_3(tr[0].x(), tr[0].y(), tr[0].z()), K::Point_3(tr[1].x(), tr[1].y(), tr[1].z()),
                        K::Point_3(tr[2].x(), tr[2].y(), tr[2].z()));
    for (int j = 0; j < 3; ++j)
      for (int a = 0; a < 3; ++a) s.v[j][a] = tr[static_cast<size_t>(j)][a];
    for (int a = 0; a < 3; ++a) {
      s.lo[a] = std::min({tr[0][a], tr[1][a], tr[2][a]});
      s.hi[a] = std::max({tr[0][a], tr[1][a], tr[2][a]});
    }
    const Eigen::Vector3d ab = tr[1] - tr[0], ac = tr[2] - tr[0], cr = ab.cross(ac);
    const double n2 = cr.squaredNorm();
    s.prunable = n2 > 0 && std::isfinite(n2) && n2 > 1e-8 * ab.squaredNorm() * ac.squaredNorm();
    const Eigen::Vector3d nrm = s.prunable ? Eigen::Vector3d(cr / std::sqrt(n2)) : Eigen::Vector3d::Zero();
    for (int a = 0; a < 3; ++a) s.n[a] = nrm[a];
    s.d = nrm.dot(tr[0]);
  }
}

TriangleDistanceTree::~TriangleDistanceTree() = default;

std::shared_ptr<const BvhLayout> TriangleDistanceTree::layout() const { return impl_->layout; }

int TriangleDistanceTree::triangle_of(int hint) const {
  if (hint < 0 || hint >= static_cast<int>(impl_->layout->order.size()))
    throw std::out_of_range("TriangleDistanceTree::triangle_of: no such position");
  return impl_->layout->order[static_cast<size_t>(hint)];
}

bool TriangleDistanceTree::within(const Eigen::Vector3d& q, double r, int& hint) const {
  const Impl& im = *impl_;
  // The skip tests of squared_distance trust the cheap distance to eps; so does this acceptance.
  const double sure = r - im.eps;
  if (!(sure > 0)) return false;
  const double r2 = sure * sure;
  const double p[3] = {q.x(), q.y(), q.z()};
  const auto close = [&](int j) {
    const Tri& s = im.tris[static_cast<size_t>(j)];
    return ericson2(s.v[0], s.v[1], s.v[2], p) <= r2;
  };
  if (hint >= 0 && hint < static_cast<int>(im.tris.size()) && close(hint)) return true;
  int stack[128];
  int top = 0;
  if (box_distance2(im.root_lo, im.root_hi, p) <= r2) stack[top++] = 0;
  while (top > 0) {
    const Node& nd = im.nodes[static_cast<size_t>(stack[--top])];
    if (nd.count > 0) {
      for (int j = nd.first; j < nd.first + nd.count; ++j) {
        const Tri& s = im.tris[static_cast<size_t>(j)];
        if (box_distance2(s.lo, s.hi, p) > r2) continue;
        if (close(j)) {
          hint = j;
          return true;
        }
      }
      continue;
    }
    const int at = static_cast<int>(&nd - im.nodes.data()), l = at + 1, rt = nd.first;
    double dl, dr;
    child_box_distances(nd.children, p, dl, dr);
    // The far child is usually popped later; fetching both now overlaps their misses.
    if (dr <= r2) __builtin_prefetch(&im.nodes[static_cast<size_t>(rt)]);
    if (dl <= r2) __builtin_prefetch(&im.nodes[static_cast<size_t>(l)]);
    // The nearer child on top: it is the likelier to hold a triangle within r.
    if (dl <= dr) {
      if (dr <= r2) stack[top++] = rt;
      if (dl <= r2) stack[top++] = l;
    } else {
      if (dl <= r2) stack[top++] = l;
      if (dr <= r2) stack[top++] = rt;
    }
  }
  return false;
}

double TriangleDistanceTree::squared_distance(const Eigen::Vector3d& q, int& hint) const {
  const Impl& im = *impl_;
  const double p[3] = {q.x(), q.y(), q.z()};
  const K::Point_3 query(p[0], p[1], p[2]);
  const K::Construct_projected_point_3 project;
  const K::Compute_squared_distance_3 sqd;
  double best2 = std::numeric_limits<double>::infinity();
  int best = -1;
  const std::vector<int>& index = im.layout->order;  // leaf position -> constructor's list
  // The value of a triangle: the closer of CGAL's projection onto it and its first vertex (CGAL
  // started from the nearest first vertex, its kd-tree's hint, and kept it unless a projection
  // came strictly closer... or as close: both give the same number).
  auto visit = [&](int t) {
    const Tri& s = im.tris[static_cast<size_t>(t)];
    const double v0 = sqd(query, s.t.vertex(0));
    const double x = sqd(query, project(s.t, query));
    const double v = std::min(v0, x);
    // Of equally close triangles the first in the constructor's list, wherever the search
    // started: none is skipped (the skip tests allow the slack), so the answer is canonical.
    if (v < best2 || (v == best2 && best >= 0 && index[static_cast<size_t>(t)] < index[static_cast<size_t>(best)]))
      best2 = v, best = t;
  };
  // Skip bound: a triangle or box farther than sqrt(best2) + eps cannot hold a closer answer.
  auto bound = [&] {
    const double r = std::sqrt(best2) + im.eps;
    return r * r;
  };
  const int start = hint >= 0 && hint < static_cast<int>(im.tris.size()) ? hint : -1;
  if (start >= 0) visit(start);
  double limit = bound();
  BvhStackEntry stack[128];  // at most depth + 1 entries: 48 surface-area levels, then median splits
  int top = 0;
  stack[top++] = {0, box_distance2(im.root_lo, im.root_hi, p)};
  while (top > 0) {
    const BvhStackEntry e = stack[--top];
    if (e.d2 > limit) continue;
    const Node& nd = im.nodes[static_cast<size_t>(e.node)];
    if (nd.count > 0) {
      for (int j = nd.first; j < nd.first + nd.count; ++j) {
        if (j == start) continue;  // measured first
        const Tri& s = im.tris[static_cast<size_t>(j)];
        if (box_distance2(s.lo, s.hi, p) > limit) continue;
        if (s.prunable) {
          const double dp = s.n[0] * p[0] + s.n[1] * p[1] + s.n[2] * p[2] - s.d;
          if (dp * dp > limit) continue;
        }
        // Within the slack of the bound, so the cheap distance decides: CGAL's projection (three
        // times the work) only for triangles that may hold the answer.
        if (ericson2(s.v[0], s.v[1], s.v[2], p) > limit) continue;
        visit(j);
        limit = bound();
      }
      continue;
    }
    const int l = e.node + 1, r = nd.first;
    double dl, dr;
    child_box_distances(nd.children, p, dl, dr);
    if (dr <= limit) __builtin_prefetch(&im.nodes[static_cast<size_t>(r)]);
    if (dl <= limit) __builtin_prefetch(&im.nodes[static_cast<size_t>(l)]);
    push_nearer_child_last(stack, top, l, dl, r, dr, [limit](double d) { return d <= limit; });
  }
  hint = best;
  return best2;
}

}  // namespace mm
