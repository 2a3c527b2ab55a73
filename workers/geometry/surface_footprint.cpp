#include "geometry/surface_footprint.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <nlohmann/json.hpp>

#include "meshio/mesh.h"
#include "support/hex.h"

namespace mm {

namespace {

// Cells are stored x fastest, then y, then z.
long flat_index(const SurfaceFootprint& f, int x, int y, int z) {
  return (static_cast<long>(z) * f.dims[1] + y) * f.dims[0] + x;
}

long cell_index(const SurfaceFootprint& f, const Eigen::Vector3d& p, int* c) {
  for (int a = 0; a < 3; ++a) {
    const double t = std::floor((p[a] - f.lo[a]) / f.cell);
    if (!(t >= 0 && t < f.dims[a])) return -1;
    c[a] = static_cast<int>(t);
  }
  return flat_index(f, c[0], c[1], c[2]);
}

bool near_occupied(const SurfaceFootprint& f, const Eigen::Vector3d& p, int reach) {
  int c[3];
  Eigen::Vector3d q = p;
  // A point just outside the box may still lie within a cell of the surface.
  for (int a = 0; a < 3; ++a) q[a] = std::clamp(q[a], f.lo[a], f.lo[a] + (f.dims[a] - 1e-9) * f.cell);
  if ((q - p).cwiseAbs().maxCoeff() > reach * f.cell) return false;
  if (cell_index(f, q, c) < 0) return false;
  for (int dz = -reach; dz <= reach; ++dz)
    for (int dy = -reach; dy <= reach; ++dy)
      for (int dx = -reach; dx <= reach; ++dx) {
        const int x = c[0] + dx, y = c[1] + dy, z = c[2] + dz;
        if (x < 0 || y < 0 || z < 0 || x >= f.dims[0] || y >= f.dims[1] || z >= f.dims[2]) continue;
        if (f.occupied[static_cast<size_t>(flat_index(f, x, y, z))]) return true;
      }
  return false;
}

bool valid_face(const Mesh& m, const std::vector<int>& face) {
  if (face.size() < 3) return false;
  for (int v : face)
    if (v < 0 || v >= m.num_vertices()) return false;
  return true;
}

// Marks in `cells` (the footprint's grid) every cell the mesh's vertices and faces touch; each
// face is sampled on a barycentric grid finer than half a cell, at most max_steps a side (a
// degenerate sliver of a huge face is capped).
void mark_surface(const SurfaceFootprint& f, const Mesh& mesh, int max_steps, std::vector<bool>& cells) {
  const Points& p = mesh.points;
  auto mark = [&](const Eigen::Vector3d& q) {
    int c[3];
    const long i = cell_index(f, q, c);
    if (i >= 0) cells[static_cast<size_t>(i)] = true;
  };
  for (Eigen::Index v = 0; v < p.rows(); ++v) mark(p.row(v).transpose());
  for (const auto& face : mesh.faces) {
    if (!valid_face(mesh, face)) continue;
    const Eigen::Vector3d a = p.row(face[0]).transpose();
    for (size_t k = 1; k + 1 < face.size(); ++k) {
      const Eigen::Vector3d b = p.row(face[k]).transpose(), c = p.row(face[k + 1]).transpose();
      const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
      const int n = std::min(max_steps, static_cast<int>(std::ceil(2 * longest / f.cell)));
      for (int i = 0; i <= n; ++i)
        for (int j = 0; i + j <= n; ++j) {
          const double u = n == 0 ? 0 : static_cast<double>(i) / n, w = n == 0 ? 0 : static_cast<double>(j) / n;
          mark(a + u * (b - a) + w * (c - a));
        }
    }
  }
}

}  // namespace

SurfaceFootprint surface_footprint(const Mesh& mesh, int cells_along_largest) {
  SurfaceFootprint f;
  if (mesh.num_vertices() == 0 || cells_along_largest < 1) return f;
  const Points& p = mesh.points;
  if (!p.allFinite()) return f;
  f.lo = p.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = p.colwise().maxCoeff().transpose();
  const double side = (hi - f.lo).maxCoeff();
  if (!(side > 0)) return f;
  f.cell = side / cells_along_largest;
  // The grid starts half a cell before the box, so the box's own faces (a CAD part's commonest
  // planes) lie mid-cell, where a watermark or noise does not move them across a cell boundary.
  f.lo.array() -= 0.5 * f.cell;
  for (int a = 0; a < 3; ++a) f.dims[a] = std::max(1, static_cast<int>(std::floor((hi[a] - f.lo[a]) / f.cell)) + 1);
  f.occupied.assign(static_cast<size_t>(f.dims[0]) * f.dims[1] * f.dims[2], false);
  mark_surface(f, mesh, 4 * cells_along_largest, f.occupied);
  return f;
}

FootprintProbe footprint_probe(const Mesh& suspect, int max_points) {
  FootprintProbe probe;
  const Eigen::Index nv = suspect.num_vertices();
  if (nv == 0 || max_points < 1) return probe;
  const Eigen::Index vs = std::min<Eigen::Index>(nv, max_points);
  const size_t nf = suspect.faces.size();
  const size_t fs = std::min<size_t>(nf, static_cast<size_t>(max_points));
  probe.points.resize(vs + static_cast<Eigen::Index>(fs), 3);
  Eigen::Index n = 0;
  for (Eigen::Index k = 0; k < vs; ++k) probe.points.row(n++) = suspect.points.row(k * nv / vs);
  for (size_t k = 0; k < fs; ++k) {
    const auto& face = suspect.faces[k * nf / fs];
    if (!valid_face(suspect, face)) continue;
    Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
    for (int v : face) c += suspect.points.row(v);
    probe.points.row(n++) = c / static_cast<double>(face.size());
  }
  probe.points.conservativeResize(n, 3);
  probe.lo = probe.points.colwise().minCoeff().transpose();
  probe.hi = probe.points.colwise().maxCoeff().transpose();
  return probe;
}

double covered_fraction(const SurfaceFootprint& footprint, const FootprintProbe& probe, int reach, int min_cells) {
  const SurfaceFootprint& f = footprint;
  if (f.empty() || probe.points.rows() == 0 || !probe.points.allFinite()) return 0;
  if ((probe.hi - probe.lo).maxCoeff() < min_cells * f.cell) return 0;
  for (int a = 0; a < 3; ++a)
    if (probe.lo[a] < f.lo[a] - f.cell || probe.hi[a] > f.lo[a] + (f.dims[a] + 1) * f.cell) return 0;
  long covered = 0;
  for (Eigen::Index k = 0; k < probe.points.rows(); ++k)
    if (near_occupied(f, probe.points.row(k).transpose(), reach)) ++covered;
  return static_cast<double>(covered) / static_cast<double>(probe.points.rows());
}

double region_agreement(const SurfaceFootprint& footprint, const Mesh& suspect) {
  const SurfaceFootprint& f = footprint;
  if (f.empty() || suspect.num_vertices() == 0 || !suspect.points.allFinite()) return 0;
  std::vector<bool> mine(f.occupied.size(), false);
  mark_surface(f, suspect, 128, mine);
  // The suspect's cell range, clamped to the grid; the part's cells outside it are not compared.
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::clamp(static_cast<int>(std::floor((suspect.points.col(a).minCoeff() - f.lo[a]) / f.cell)), 0, f.dims[a] - 1);
    hi[a] = std::clamp(static_cast<int>(std::floor((suspect.points.col(a).maxCoeff() - f.lo[a]) / f.cell)), 0, f.dims[a] - 1);
  }
  long both = 0, either = 0;
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y)
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const size_t i = static_cast<size_t>(flat_index(f, x, y, z));
        both += mine[i] && f.occupied[i];
        either += mine[i] || f.occupied[i];
      }
  return either == 0 ? 0 : static_cast<double>(both) / static_cast<double>(either);
}

std::string SurfaceFootprint::to_json() const {
  nlohmann::json j;
  j["lo"] = {lo[0], lo[1], lo[2]};
  j["cell"] = cell;
  j["dims"] = {dims[0], dims[1], dims[2]};
  std::vector<std::uint8_t> bytes((occupied.size() + 7) / 8, 0);
  for (size_t i = 0; i < occupied.size(); ++i)
    if (occupied[i]) bytes[i / 8] = static_cast<std::uint8_t>(bytes[i / 8] | (1u << (i % 8)));
  j["cells"] = support::to_hex(bytes.data(), bytes.size());
  return j.dump();
}

SurfaceFootprint SurfaceFootprint::from_json(const std::string& text) {
  try {
    const auto j = nlohmann::json::parse(text);
    SurfaceFootprint f;
    for (int a = 0; a < 3; ++a) {
      f.lo[a] = j.at("lo").at(a).get<double>();
      f.dims[a] = j.at("dims").at(a).get<int>();
      if (f.dims[a] < 1 || f.dims[a] > 4096) throw InputError("surface footprint", "grid size out of range");
    }
    f.cell = j.at("cell").get<double>();
    const size_t n = static_cast<size_t>(f.dims[0]) * f.dims[1] * f.dims[2];
    if (!(f.cell > 0) || !std::isfinite(f.cell) || !f.lo.allFinite() || n > (size_t{1} << 24))
      throw InputError("surface footprint", "malformed grid");
    const std::string hex = j.at("cells").get<std::string>();
    if (hex.size() != 2 * ((n + 7) / 8)) throw InputError("surface footprint", "cell bits do not match the grid");
    std::vector<std::uint8_t> bytes;
    try {
      bytes = support::from_hex(hex);
    } catch (const std::invalid_argument&) {
      throw InputError("surface footprint", "cell bits are not hex");
    }
    f.occupied.assign(n, false);
    for (size_t i = 0; i < n; ++i) f.occupied[i] = (bytes[i / 8] >> (i % 8)) & 1;
    return f;
  } catch (const nlohmann::json::exception& e) {
    throw InputError("surface footprint", std::string("malformed: ") + e.what());
  }
}

}  // namespace mm
