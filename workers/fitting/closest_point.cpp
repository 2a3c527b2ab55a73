#include "fitting/closest_point.h"

#include <CGAL/AABB_segment_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <algorithm>

namespace mm {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Tri = K::Triangle_3;
using Seg = K::Segment_3;
using TriIt = std::vector<Tri>::const_iterator;
using SegIt = std::vector<Seg>::const_iterator;
using TriTree = CGAL::AABB_tree<CGAL::AABB_traits<K, CGAL::AABB_triangle_primitive<K, TriIt>>>;
using SegTree = CGAL::AABB_tree<CGAL::AABB_traits<K, CGAL::AABB_segment_primitive<K, SegIt>>>;

K::Point_3 cg(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }
Eigen::Vector3d ei(const K::Point_3& p) { return {p.x(), p.y(), p.z()}; }

// Barycentric weights of p (assumed on or near triangle abc), clamped to the triangle.
Eigen::Vector3d barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                            const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  Eigen::Vector3d e1 = b - a, e2 = c - a, d = p - a;
  double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2);
  double det = d11 * d22 - d12 * d12;
  if (!(det > 0)) return {1, 0, 0};
  double u = (d22 * e1.dot(d) - d12 * e2.dot(d)) / det;
  double v = (d11 * e2.dot(d) - d12 * e1.dot(d)) / det;
  Eigen::Vector3d w(1 - u - v, u, v);
  w = w.cwiseMax(0.0);
  double s = w.sum();
  return s > 0 ? Eigen::Vector3d(w / s) : Eigen::Vector3d(1, 0, 0);
}

}  // namespace

struct TriangleIndex::Impl {
  std::vector<Tri> tris;
  std::vector<int> id;       // tree triangle -> caller's triangle index
  std::vector<int> tree_of;  // caller's triangle index -> tree triangle (-1: degenerate)
  TriTree tree;
  TriangleHit hit(const Eigen::Vector3d& q, const K::Point_3& pt, TriIt it) const {
    const Tri& tri = *it;
    TriangleHit h;
    h.triangle = id[static_cast<size_t>(it - tris.begin())];
    h.point = ei(pt);
    h.barycentric = barycentric(h.point, ei(tri[0]), ei(tri[1]), ei(tri[2]));
    h.distance = (h.point - q).norm();
    return h;
  }
};

TriangleIndex::TriangleIndex(const Points& points, std::vector<std::array<int, 3>> triangles,
                             bool eager_search_tree)
    : impl_(std::make_unique<Impl>()), triangles_(std::move(triangles)) {
  for (size_t t = 0; t < triangles_.size(); ++t) {
    const auto& f = triangles_[t];
    Tri tri(cg(points.row(f[0])), cg(points.row(f[1])), cg(points.row(f[2])));
    if (tri.is_degenerate()) continue;
    impl_->tris.push_back(tri);
    impl_->id.push_back(static_cast<int>(t));
  }
  impl_->tree_of.assign(triangles_.size(), -1);
  for (size_t k = 0; k < impl_->id.size(); ++k) impl_->tree_of[impl_->id[k]] = static_cast<int>(k);
  impl_->tree.rebuild(impl_->tris.begin(), impl_->tris.end());
  // CGAL builds the same kd-tree lazily (thread-safely) on the first query without a hint.
  if (!impl_->tris.empty() && eager_search_tree) impl_->tree.accelerate_distance_queries();
}
TriangleIndex::~TriangleIndex() = default;
bool TriangleIndex::empty() const { return impl_->tris.empty(); }

TriangleHit TriangleIndex::closest(const Eigen::Vector3d& q) const {
  auto [pt, it] = impl_->tree.closest_point_and_primitive(cg(q));
  return impl_->hit(q, pt, it);
}

TriangleHit TriangleIndex::closest(const Eigen::Vector3d& q, const TriangleHint& hint) const {
  if (hint.triangle < 0 || hint.triangle >= static_cast<int>(impl_->tree_of.size()) ||
      impl_->tree_of[hint.triangle] < 0)
    return closest(q);
  TriIt hint_it = impl_->tris.begin() + impl_->tree_of[hint.triangle];
  auto [pt, it] = impl_->tree.closest_point_and_primitive(cg(q), std::make_pair(cg(hint.point), hint_it));
  return impl_->hit(q, pt, it);
}

struct SegmentIndex::Impl {
  std::vector<Seg> segs;
  std::vector<int> id;
  std::vector<int> tree_of;
  SegTree tree;
  SegmentHit hit(const Eigen::Vector3d& q, const K::Point_3& pt, SegIt it) const {
    const Seg& seg = *it;
    SegmentHit h;
    h.segment = id[static_cast<size_t>(it - segs.begin())];
    h.point = ei(pt);
    Eigen::Vector3d a = ei(seg.source()), b = ei(seg.target());
    double len2 = (b - a).squaredNorm();
    h.t = len2 > 0 ? std::clamp((h.point - a).dot(b - a) / len2, 0.0, 1.0) : 0.0;
    h.distance = (h.point - q).norm();
    return h;
  }
};

SegmentIndex::SegmentIndex(const Points& points, std::vector<std::pair<int, int>> segments,
                           bool eager_search_tree)
    : impl_(std::make_unique<Impl>()), segments_(std::move(segments)) {
  for (size_t s = 0; s < segments_.size(); ++s) {
    Seg seg(cg(points.row(segments_[s].first)), cg(points.row(segments_[s].second)));
    if (seg.is_degenerate()) continue;
    impl_->segs.push_back(seg);
    impl_->id.push_back(static_cast<int>(s));
  }
  impl_->tree_of.assign(segments_.size(), -1);
  for (size_t k = 0; k < impl_->id.size(); ++k) impl_->tree_of[impl_->id[k]] = static_cast<int>(k);
  impl_->tree.rebuild(impl_->segs.begin(), impl_->segs.end());
  if (!impl_->segs.empty() && eager_search_tree) impl_->tree.accelerate_distance_queries();
}
SegmentIndex::~SegmentIndex() = default;
bool SegmentIndex::empty() const { return impl_->segs.empty(); }

SegmentHit SegmentIndex::closest(const Eigen::Vector3d& q) const {
  auto [pt, it] = impl_->tree.closest_point_and_primitive(cg(q));
  return impl_->hit(q, pt, it);
}

SegmentHit SegmentIndex::closest(const Eigen::Vector3d& q, const SegmentHint& hint) const {
  if (hint.segment < 0 || hint.segment >= static_cast<int>(impl_->tree_of.size()) ||
      impl_->tree_of[hint.segment] < 0)
    return closest(q);
  SegIt hint_it = impl_->segs.begin() + impl_->tree_of[hint.segment];
  auto [pt, it] = impl_->tree.closest_point_and_primitive(cg(q), std::make_pair(cg(hint.point), hint_it));
  return impl_->hit(q, pt, it);
}

std::vector<std::array<int, 3>> triangle_list(const Mesh& mesh) {
  std::vector<std::array<int, 3>> out;
  out.reserve(mesh.faces.size() * 2);
  for (const auto& f : mesh.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) out.push_back({f[0], f[k], f[k + 1]});
  return out;
}

}  // namespace mm
