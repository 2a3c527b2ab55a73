// Interim reader/writer through OpenMesh's PolyMesh (to be hardened: raw importer, welding,
// validation, non-manifold repair).
#include "meshio/read_mesh.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <filesystem>

namespace mm {
namespace {
struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
};
using OMesh = OpenMesh::PolyMesh_ArrayKernelT<Traits>;
}  // namespace

Mesh read_mesh(const std::string& path) {
  if (!std::filesystem::exists(path)) throw InputError(path, "no such file");
  OMesh om;
  if (!OpenMesh::IO::read_mesh(om, path)) throw InputError(path, "could not be read");
  Mesh m;
  m.points.resize(static_cast<Eigen::Index>(om.n_vertices()), 3);
  for (auto v : om.vertices()) {
    auto p = om.point(v);
    m.points.row(v.idx()) << p[0], p[1], p[2];
  }
  for (auto f : om.faces()) {
    std::vector<int> face;
    for (auto v : om.fv_range(f)) face.push_back(v.idx());
    m.faces.push_back(std::move(face));
  }
  return m;
}

void write_mesh(const Mesh& mesh, const std::string& path) {
  OMesh om;
  std::vector<OMesh::VertexHandle> vh;
  for (int i = 0; i < mesh.num_vertices(); ++i)
    vh.push_back(om.add_vertex(OMesh::Point(mesh.points(i, 0), mesh.points(i, 1), mesh.points(i, 2))));
  for (const auto& f : mesh.faces) {
    std::vector<OMesh::VertexHandle> h;
    for (int i : f) h.push_back(vh[i]);
    om.add_face(h);
  }
  OpenMesh::IO::Options opt;
  if (!OpenMesh::IO::write_mesh(om, path, opt, 17)) throw InputError(path, "could not be written");
}

}  // namespace mm
