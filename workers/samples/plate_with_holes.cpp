#include "samples/plate_with_holes.h"

#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

#include "samples/shape_building.h"

namespace mm::samples {

Mesh plate_with_holes(const PlateWithHoles& p) {
  const int m = p.segments_per_side;
  if (p.cells_x < 1 || p.cells_y < 1 || m < 2 || m % 2 || p.rings < 1 || p.layers < 1 ||
      !(p.hole_radius > 0) || !(2 * p.hole_radius < p.cell) || !(p.thickness > 0))
    throw std::invalid_argument("plate_with_holes: invalid parameters");
  std::set<std::pair<int, int>> holes(p.holes.begin(), p.holes.end());
  for (auto [cx, cy] : holes)
    if (cx < 0 || cy < 0 || cx >= p.cells_x || cy >= p.cells_y)
      throw std::invalid_argument("plate_with_holes: hole outside the cell grid");
  Region r;
  const double h = p.cell / m;
  // Points on the lattice of cell-side divisions are shared between neighbouring cells.
  std::map<std::pair<int, int>, int> lattice;
  auto lattice_point = [&](int i, int j) {
    auto [it, inserted] = lattice.try_emplace({i, j}, static_cast<int>(r.points.size()));
    if (inserted) r.points.emplace_back(i * h, j * h);
    return it->second;
  };
  for (int cy = 0; cy < p.cells_y; ++cy)
    for (int cx = 0; cx < p.cells_x; ++cx) {
      const int i0 = cx * m, j0 = cy * m;
      if (!holes.count({cx, cy})) {
        for (int i = 0; i < m; ++i)
          for (int j = 0; j < m; ++j)
            r.faces.push_back({lattice_point(i0 + i, j0 + j), lattice_point(i0 + i + 1, j0 + j),
                               lattice_point(i0 + i + 1, j0 + j + 1), lattice_point(i0 + i, j0 + j + 1)});
        continue;
      }
      // Square perimeter, counter-clockwise from the lower-left corner, 4m lattice points;
      // the circle gets 4m points at uniform angles starting at the same diagonal.
      std::vector<std::pair<int, int>> square;
      for (int q = 0; q < m; ++q) square.push_back({i0 + q, j0});
      for (int q = 0; q < m; ++q) square.push_back({i0 + m, j0 + q});
      for (int q = 0; q < m; ++q) square.push_back({i0 + m - q, j0 + m});
      for (int q = 0; q < m; ++q) square.push_back({i0, j0 + m - q});
      const Eigen::Vector2d center((cx + 0.5) * p.cell, (cy + 0.5) * p.cell);
      const int n = 4 * m;
      std::vector<std::vector<int>> ring(static_cast<size_t>(p.rings + 1), std::vector<int>(static_cast<size_t>(n)));
      for (int q = 0; q < n; ++q) {
        double phi = -0.75 * M_PI + 2 * M_PI * q / n;
        Eigen::Vector2d on_circle = center + p.hole_radius * Eigen::Vector2d(std::cos(phi), std::sin(phi));
        int outer = lattice_point(square[static_cast<size_t>(q)].first, square[static_cast<size_t>(q)].second);
        Eigen::Vector2d on_square = r.points[static_cast<size_t>(outer)];
        for (int l = 0; l < p.rings; ++l) {
          ring[static_cast<size_t>(l)][static_cast<size_t>(q)] = static_cast<int>(r.points.size());
          r.points.push_back(on_circle + (on_square - on_circle) * (double(l) / p.rings));
        }
        ring[static_cast<size_t>(p.rings)][static_cast<size_t>(q)] = outer;
      }
      for (int l = 0; l < p.rings; ++l)
        for (int q = 0; q < n; ++q) {
          auto at = [&](int ll, int qq) { return ring[static_cast<size_t>(ll)][static_cast<size_t>(qq % n)]; };
          r.faces.push_back({at(l, q), at(l + 1, q), at(l + 1, q + 1), at(l, q + 1)});
        }
    }
  return extrude(r, p.thickness, p.layers);
}

}  // namespace mm::samples
