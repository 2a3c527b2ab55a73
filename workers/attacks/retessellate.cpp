#include "attacks/retessellate.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/detect_features.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_ratio_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/alpha_wrap_3.h>

#include <array>
#include <numeric>
#include <stdexcept>
#include <string>

#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"

namespace mm::attacks {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;

double diagonal(const Mesh& mesh) {
  return (mesh.points.colwise().maxCoeff() - mesh.points.colwise().minCoeff()).norm();
}

// The mesh triangulated, as CGAL's point and triangle lists.
void triangle_soup(const Mesh& mesh, std::vector<Point>& points, std::vector<std::array<std::size_t, 3>>& triangles) {
  const Mesh t = triangulate(mesh);
  points.reserve(static_cast<std::size_t>(t.num_vertices()));
  for (int v = 0; v < t.num_vertices(); ++v) points.emplace_back(t.points(v, 0), t.points(v, 1), t.points(v, 2));
  triangles.reserve(t.faces.size());
  for (const auto& f : t.faces)
    triangles.push_back({static_cast<std::size_t>(f[0]), static_cast<std::size_t>(f[1]), static_cast<std::size_t>(f[2])});
}

SurfaceMesh to_surface_mesh(const Mesh& mesh, const std::string& what) {
  check_mesh(mesh, what);
  std::vector<Point> points;
  std::vector<std::array<std::size_t, 3>> triangles;
  triangle_soup(mesh, points, triangles);
  // Orienting the soup duplicates non-manifold vertices, so every input becomes a polygon mesh.
  PMP::orient_polygon_soup(points, triangles);
  SurfaceMesh sm;
  PMP::polygon_soup_to_polygon_mesh(points, triangles, sm);
  if (sm.number_of_faces() == 0) throw InputError(what, "no faces CGAL can take as a polygon mesh");
  return sm;
}

Mesh from_surface_mesh(SurfaceMesh& sm) {
  sm.collect_garbage();
  Mesh out;
  out.points.resize(static_cast<Eigen::Index>(sm.number_of_vertices()), 3);
  for (auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    out.points.row(static_cast<Eigen::Index>(v.idx())) << p.x(), p.y(), p.z();
  }
  for (auto f : sm.faces()) {
    std::vector<int> face;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) face.push_back(static_cast<int>(v.idx()));
    out.faces.push_back(std::move(face));
  }
  return out;
}

}  // namespace

Mesh remesh_isotropic(const Mesh& mesh, double edge_length, int iterations) {
  if (!(edge_length > 0) || iterations < 1) throw std::invalid_argument("remesh_isotropic: bad edge length or iterations");
  const double target = edge_length * diagonal(mesh);
  auto remesh = [&](bool protect) {
    SurfaceMesh sm = to_surface_mesh(mesh, "remesh");
    auto is_feature = sm.add_property_map<SurfaceMesh::Edge_index, bool>("e:is_feature", false).first;
    PMP::detect_sharp_edges(sm, 60.0, is_feature);
    std::vector<SurfaceMesh::Edge_index> features;
    for (auto e : sm.edges())
      if (is_feature[e]) features.push_back(e);
    PMP::split_long_edges(features, target, sm, CGAL::parameters::edge_is_constrained_map(is_feature));
    PMP::isotropic_remeshing(sm.faces(), target, sm,
                             CGAL::parameters::number_of_iterations(static_cast<unsigned>(iterations))
                                 .edge_is_constrained_map(is_feature)
                                 .protect_constraints(protect));
    return from_surface_mesh(sm);
  };
  // CGAL's protected-constraint bookkeeping fails (std::out_of_range from a map lookup) on some
  // feature networks, e.g. a decoded subdivision surface's dense crease chains; the sharp edges
  // then stay constrained but may be split and flipped along themselves, as mesh tools do.
  try {
    return remesh(true);
  } catch (const std::out_of_range&) {
    return remesh(false);
  }
}

Mesh simplify_edges(const Mesh& mesh, double keep_fraction) {
  if (!(keep_fraction > 0 && keep_fraction <= 1)) throw std::invalid_argument("simplify_edges: keep_fraction outside (0, 1]");
  SurfaceMesh sm = to_surface_mesh(mesh, "simplify");
  namespace SMS = CGAL::Surface_mesh_simplification;
  SMS::Count_ratio_stop_predicate<SurfaceMesh> stop(keep_fraction);
  SMS::edge_collapse(sm, stop);
  return from_surface_mesh(sm);
}

Mesh alpha_wrap(const Mesh& mesh, double alpha, double offset) {
  if (!(alpha > 0) || !(offset > 0)) throw std::invalid_argument("alpha_wrap: alpha and offset must be positive");
  check_mesh(mesh, "wrap");
  std::vector<Point> points;
  std::vector<std::array<std::size_t, 3>> triangles;
  triangle_soup(mesh, points, triangles);
  const double d = diagonal(mesh);
  SurfaceMesh wrap;
  CGAL::alpha_wrap_3(points, triangles, alpha * d, offset * d, wrap);
  return from_surface_mesh(wrap);
}

}  // namespace mm::attacks
