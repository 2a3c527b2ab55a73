// Re-tessellation attacks for the registration tests: quadric decimation (OpenMesh) keeps
// surviving vertices exactly where they were, on the surface, with unrelated connectivity.
#pragma once
// OpenMesh's property vectors of Vec3d trip GCC 12's -Wmaybe-uninitialized inside libstdc++.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include "meshio/mesh.h"
#include "subdivision/decompress.h"

namespace mm::test {

struct DoubleTraits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using OMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

// Decimates `mesh` (triangulated first) to about `target_vertices` vertices.
inline Mesh decimate(const Mesh& mesh, int target_vertices) {
  const Mesh tri = triangulate(mesh);
  OMesh om;
  std::vector<OMesh::VertexHandle> vh;
  for (int v = 0; v < tri.num_vertices(); ++v)
    vh.push_back(om.add_vertex(OMesh::Point(tri.points(v, 0), tri.points(v, 1), tri.points(v, 2))));
  for (const auto& f : tri.faces) om.add_face(vh[f[0]], vh[f[1]], vh[f[2]]);
  OpenMesh::Decimater::DecimaterT<OMesh> dec(om);
  OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
  dec.add(quadric);
  dec.initialize();
  dec.decimate_to(static_cast<size_t>(target_vertices));
  om.garbage_collection();
  Mesh out;
  out.points.resize(static_cast<Eigen::Index>(om.n_vertices()), 3);
  for (auto v : om.vertices()) {
    const auto& p = om.point(v);
    out.points.row(v.idx()) << p[0], p[1], p[2];
  }
  for (auto f : om.faces()) {
    std::vector<int> face;
    for (auto v : om.fv_range(f)) face.push_back(v.idx());
    out.faces.push_back(face);
  }
  return out;
}

}  // namespace mm::test

#pragma GCC diagnostic pop
