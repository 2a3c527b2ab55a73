#include "attacks/crop.h"

#include <string>

namespace mm::attacks {

Mesh crop_along_longest_axis(const Mesh& mesh, double keep_fraction, bool from_high) {
  if (!(keep_fraction > 0 && keep_fraction <= 1))
    throw std::invalid_argument("crop_along_longest_axis: keep_fraction outside (0, 1]");
  check_mesh(mesh, "crop");
  const Eigen::RowVector3d low = mesh.points.colwise().minCoeff(), high = mesh.points.colwise().maxCoeff();
  Eigen::Index axis = 0;
  (high - low).maxCoeff(&axis);
  const double extent = high[axis] - low[axis];
  const double cut = from_high ? high[axis] - keep_fraction * extent : low[axis] + keep_fraction * extent;
  std::vector<int> new_index(static_cast<std::size_t>(mesh.num_vertices()), -1);
  Mesh out;
  for (const auto& face : mesh.faces) {
    double centroid = 0;
    for (int v : face) centroid += mesh.points(v, axis);
    centroid /= static_cast<double>(face.size());
    if (from_high ? centroid < cut : centroid > cut) continue;
    out.faces.push_back(face);
    for (int v : face) new_index[static_cast<std::size_t>(v)] = 0;
  }
  if (out.faces.empty()) throw InputError("crop", "no face left keeping " + std::to_string(keep_fraction) + " of the part");
  int kept = 0;
  for (int& i : new_index)
    if (i == 0) i = kept++;
  out.points.resize(kept, 3);
  for (int v = 0; v < mesh.num_vertices(); ++v)
    if (new_index[static_cast<std::size_t>(v)] >= 0) out.points.row(new_index[static_cast<std::size_t>(v)]) = mesh.points.row(v);
  for (auto& face : out.faces)
    for (int& v : face) v = new_index[static_cast<std::size_t>(v)];
  return out;
}

}  // namespace mm::attacks
