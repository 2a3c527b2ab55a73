#include "geometry/closest_point.h"

#include "geometry/closest_point_bvh.h"

namespace mm {

struct TriangleIndex::Impl {
  TriangleBvh bvh;
};

TriangleIndex::TriangleIndex(const Points& points, std::vector<std::array<int, 3>> triangles)
    : impl_(new Impl{TriangleBvh(points, std::move(triangles))}) {}
TriangleIndex::~TriangleIndex() = default;
bool TriangleIndex::empty() const { return impl_->bvh.empty(); }

TriangleHit TriangleIndex::closest(const Eigen::Vector3d& q) const { return impl_->bvh.closest(q); }

TriangleHit TriangleIndex::closest(const Eigen::Vector3d& q, int start_triangle) const {
  return impl_->bvh.closest(q, start_triangle);
}
const std::array<int, 3>& TriangleIndex::triangle(int t) const { return impl_->bvh.triangle(t); }

TriangleHit HintedClosest::closest(const Eigen::Vector3d& q, Eigen::Index number) {
  const auto k = static_cast<std::size_t>(number);
  if (k >= hints_.size()) hints_.resize(k + 1, -1);
  const TriangleHit hit = index_.closest(q, hints_[k]);
  hints_[k] = hit.triangle;
  return hit;
}

std::vector<std::array<int, 3>> triangle_list(const Mesh& mesh) {
  std::vector<std::array<int, 3>> out;
  out.reserve(mesh.faces.size() * 2);
  for (const auto& f : mesh.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) out.push_back({f[0], f[k], f[k + 1]});
  return out;
}

}  // namespace mm
