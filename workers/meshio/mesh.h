// The indexed polygon mesh every science library works on: positions plus faces as vertex
// index lists (triangles and quads, any polygon allowed). Vertex order is meaningful: the
// spectral basis and the watermark depend on it, so nothing reorders vertices silently.
#pragma once
#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

namespace mm {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct Mesh {
  Points points;                          // n x 3
  std::vector<std::vector<int>> faces;    // counter-clockwise vertex indices
  // Subdivision tags, used by control polyhedra: infinitely sharp crease edges (i < j) and
  // corner vertices. Empty for ordinary meshes.
  std::vector<std::pair<int, int>> creases;
  std::vector<int> corners;
  int num_vertices() const { return static_cast<int>(points.rows()); }
  int num_faces() const { return static_cast<int>(faces.size()); }
};

// Undirected edges (i < j), sorted, each once.
std::vector<std::pair<int, int>> unique_edges(const Mesh& mesh);

// A problem with an input file or stream: names it and says what is wrong.
class InputError : public std::runtime_error {
 public:
  InputError(const std::string& source, const std::string& reason)
      : std::runtime_error(source + ": " + reason), source_(source), reason_(reason) {}
  const std::string& source() const { return source_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string source_, reason_;
};

// The structural minimum every algorithm assumes of a handed-in mesh: at least one vertex and one
// face, finite coordinates, faces of 3+ in-range vertex indices. Throws InputError(source, reason).
void check_mesh(const Mesh& mesh, const std::string& source);

}  // namespace mm
