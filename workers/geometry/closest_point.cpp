#include "geometry/closest_point.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <algorithm>
#include <cmath>
#include <optional>

namespace mm {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Tri = K::Triangle_3;
using TriIt = std::vector<Tri>::const_iterator;
using TriPrimitive = CGAL::AABB_triangle_primitive<K, TriIt>;

// Supporting plane a x + b y + c z + d = 0 of a tree triangle, as CGAL computes it.
struct TriPlane {
  double a, b, c, d;
  double extent;  // largest absolute vertex coordinate
  bool prunable;  // not a sliver: the plane's distance is accurate enough to skip on
};

// CGAL's AABB traits with the point-triangle projection done on planes computed once per tree
// instead of once per visited triangle and query. The arithmetic is CGAL's own
// (CommonKernelFunctors::Construct_projected_point_3 with Simple_cartesian<double>: the same
// operations in the same order), so the answers are bit for bit those of the stock traits.
class FastTriTraits : public CGAL::AABB_traits<K, TriPrimitive> {
 public:
  TriIt first{};                     // the tree's triangles start here
  const TriPlane* planes = nullptr;  // parallel to them

  class Closest_point {
   public:
    explicit Closest_point(const FastTriTraits& t) : t_(t) {}
    K::Point_3 operator()(const K::Point_3& p, const TriPrimitive& pr, const K::Point_3& bound) const {
      const size_t k = static_cast<size_t>(pr.id() - t_.first);
      const TriPlane& h = t_.planes[k];
      // Most visited triangles are farther than the best so far: their plane alone says so.
      // The plane distance is below the triangle distance; the margin (1e-9 of the coordinates'
      // size s) is far above the rounding of both distances for a triangle whose sine of its
      // angle at the third vertex exceeds 1e-4 (about 1e-15 s / 1e-4), so a skipped triangle is
      // one CGAL's comparison would have rejected too. Slivers are always projected.
      if (h.prunable) {
        const double den = h.a * h.a + h.b * h.b + h.c * h.c;
        const double num = h.a * p.x() + h.b * p.y() + h.c * p.z() + h.d;
        const double s = std::max({1.0, h.extent, std::abs(p.x()), std::abs(p.y()), std::abs(p.z())});
        const double lim = std::sqrt(CGAL::squared_distance(p, bound)) + 1e-9 * s;
        if (num * num > den * (lim * lim)) return bound;
      }
      const K::Point_3 q = project(*pr.id(), h, p);
      return CGAL::compare_distance_to_point(p, q, bound) == CGAL::LARGER ? bound : q;
    }

   private:
    const FastTriTraits& t_;
  };
  Closest_point closest_point_object() const { return Closest_point(*this); }

  // Is the box closer than the best point so far? CGAL's sphere-box test
  // (do_intersect_sphere_box_3, exact comparisons) without building a sphere per node.
  class Compare_distance {
   public:
    CGAL::Comparison_result operator()(const K::Point_3& p, const CGAL::Bbox_3& bb,
                                       const K::Point_3& bound) const {
      const double sr = CGAL::squared_distance(p, bound);
      double distance = 0, d;
      if (p.x() < bb.xmin()) {
        d = bb.xmin() - p.x();
        d = d * d;
        if (d > sr) return CGAL::LARGER;
        distance = d;
      } else if (p.x() > bb.xmax()) {
        d = p.x() - bb.xmax();
        d = d * d;
        if (d > sr) return CGAL::LARGER;
        distance = d;
      }
      if (p.y() < bb.ymin()) {
        d = bb.ymin() - p.y();
        d = d * d;
        if (d > sr) return CGAL::LARGER;
        distance += d;
      } else if (p.y() > bb.ymax()) {
        d = p.y() - bb.ymax();
        d = d * d;
        if (d > sr) return CGAL::LARGER;
        distance += d;
      }
      if (p.z() < bb.zmin()) {
        d = bb.zmin() - p.z();
        distance += d * d;
      } else if (p.z() > bb.zmax()) {
        d = p.z() - bb.zmax();
        distance += d * d;
      }
      return distance <= sr ? CGAL::SMALLER : CGAL::LARGER;
    }
  };
  Compare_distance compare_distance_object() const { return Compare_distance(); }

  static K::Point_3 project(const Tri& tri, const TriPlane& h, const K::Point_3& o) {
    if (h.a == 0 && h.b == 0 && h.c == 0) return K::Construct_projected_point_3()(tri, o);
    // projection_planeC3
    const double num = h.a * o.x() + h.b * o.y() + h.c * o.z() + h.d;
    const double den = h.a * h.a + h.b * h.b + h.c * h.c;
    const double lambda = num / den;
    const K::Point_3 proj(o.x() - lambda * h.a, o.y() - lambda * h.b, o.z() - lambda * h.c);
    // is_inside_triangle_3
    const K::Point_3 &t0 = tri[0], &t1 = tri[1], &t2 = tri[2];
    K::Point_3 result;
    bool outside = false;
    if (edge(h, t0, t1, proj, result, outside) || edge(h, t1, t2, proj, result, outside) ||
        edge(h, t2, t0, proj, result, outside))
      return result;
    if (!outside) return proj;
    // nearest_point_3
    const double d1 = CGAL::squared_distance(proj, t0), d2 = CGAL::squared_distance(proj, t1),
                 d3 = CGAL::squared_distance(proj, t2);
    if (d2 >= d1 && d3 >= d1) return t0;
    if (d3 >= d2) return t1;
    return t2;
  }

 private:
  // is_inside_triangle_3_aux, w = the plane's normal (a, b, c).
  static bool edge(const TriPlane& w, const K::Point_3& p1, const K::Point_3& p2, const K::Point_3& q,
                   K::Point_3& result, bool& outside) {
    const double ex = p2.x() - p1.x(), ey = p2.y() - p1.y(), ez = p2.z() - p1.z();
    const double qx = q.x() - p1.x(), qy = q.y() - p1.y(), qz = q.z() - p1.z();
    const double vx = ey * qz - ez * qy, vy = ez * qx - ex * qz, vz = ex * qy - ey * qx;
    if (vx * w.a + vy * w.b + vz * w.c < 0.0) {
      const double fx = q.x() - p2.x(), fy = q.y() - p2.y(), fz = q.z() - p2.z();
      const double gx = p1.x() - p2.x(), gy = p1.y() - p2.y(), gz = p1.z() - p2.z();
      if (qx * ex + qy * ey + qz * ez >= 0.0 && fx * gx + fy * gy + fz * gz >= 0.0) {
        // Construct_projected_point_3(Line_3(p1, p2), q)
        const double lambda = (ex * qx + ey * qy + ez * qz) / (ex * ex + ey * ey + ez * ez);
        result = K::Point_3(p1.x() + lambda * ex, p1.y() + lambda * ey, p1.z() + lambda * ez);
        return true;
      }
      outside = true;
    }
    return false;
  }
};

TriPlane plane_of(const Tri& t) {
  // plane_from_pointsC3(p, q, r)
  const K::Point_3 &p = t[0], &q = t[1], &r = t[2];
  const double rpx = p.x() - r.x(), rpy = p.y() - r.y(), rpz = p.z() - r.z();
  const double rqx = q.x() - r.x(), rqy = q.y() - r.y(), rqz = q.z() - r.z();
  TriPlane h;
  h.a = rpy * rqz - rqy * rpz;
  h.b = rpz * rqx - rqz * rpx;
  h.c = rpx * rqy - rqx * rpy;
  h.d = -h.a * r.x() - h.b * r.y() - h.c * r.z();
  h.extent = 0;
  for (int k = 0; k < 3; ++k)
    h.extent = std::max({h.extent, std::abs(t[k].x()), std::abs(t[k].y()), std::abs(t[k].z())});
  const double rp2 = rpx * rpx + rpy * rpy + rpz * rpz, rq2 = rqx * rqx + rqy * rqy + rqz * rqz;
  const double n2 = h.a * h.a + h.b * h.b + h.c * h.c;
  h.prunable = n2 > 1e-8 * rp2 * rq2;  // sin^2 of the angle at r
  return h;
}

using TriTree = CGAL::AABB_tree<FastTriTraits>;

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
  std::vector<TriPlane> planes;  // per tree triangle, for FastTriTraits
  std::optional<TriTree> tree;   // built with traits pointing at tris and planes
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

TriangleIndex::TriangleIndex(const Points& points, std::vector<std::array<int, 3>> triangles)
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
  impl_->planes.reserve(impl_->tris.size());
  for (const Tri& tri : impl_->tris) impl_->planes.push_back(plane_of(tri));
  // The tree keeps its own copy of the traits.
  FastTriTraits traits;
  traits.first = impl_->tris.begin();
  traits.planes = impl_->planes.data();
  impl_->tree.emplace(traits);
  impl_->tree->rebuild(impl_->tris.begin(), impl_->tris.end());
  if (!impl_->tris.empty()) impl_->tree->accelerate_distance_queries();
}
TriangleIndex::~TriangleIndex() = default;
bool TriangleIndex::empty() const { return impl_->tris.empty(); }

TriangleHit TriangleIndex::closest(const Eigen::Vector3d& q) const {
  auto [pt, it] = impl_->tree->closest_point_and_primitive(cg(q));
  return impl_->hit(q, pt, it);
}

TriangleHit HintedClosest::closest(const Eigen::Vector3d& q, Eigen::Index number) {
  const auto k = static_cast<std::size_t>(number);
  if (k >= hints_.size()) hints_.resize(k + 1);
  TriangleHint& hint = hints_[k];
  const TriangleHit hit = hint.triangle < 0 ? index_.closest(q) : index_.closest(q, hint);
  hint = TriangleHint{hit.triangle, hit.point};
  return hit;
}

TriangleHit TriangleIndex::closest(const Eigen::Vector3d& q, const TriangleHint& hint) const {
  if (hint.triangle < 0 || hint.triangle >= static_cast<int>(impl_->tree_of.size()) ||
      impl_->tree_of[hint.triangle] < 0)
    return closest(q);
  TriIt hint_it = impl_->tris.begin() + impl_->tree_of[hint.triangle];
  auto [pt, it] = impl_->tree->closest_point_and_primitive(cg(q), std::make_pair(cg(hint.point), hint_it));
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
