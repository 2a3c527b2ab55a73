#include "fitting/segmentation.h"

#include <algorithm>
#include <map>
#include <set>

namespace mm {

Segmentation segment(const Mesh& mesh, const Features& features) {
  Segmentation out;
  const int nf = mesh.num_faces(), nv = mesh.num_vertices();
  std::set<std::pair<int, int>> sharp(features.sharp_edges.begin(), features.sharp_edges.end());

  // Faces adjacent across non-sharp edges.
  std::map<std::pair<int, int>, std::vector<int>> edge_faces;
  for (int f = 0; f < nf; ++f) {
    const auto& face = mesh.faces[f];
    for (size_t k = 0; k < face.size(); ++k) {
      int a = face[k], b = face[(k + 1) % face.size()];
      if (a != b) edge_faces[{std::min(a, b), std::max(a, b)}].push_back(f);
    }
  }
  std::vector<std::vector<int>> adj(nf);
  for (const auto& [e, faces] : edge_faces) {
    if (sharp.count(e) || faces.size() != 2) continue;
    adj[faces[0]].push_back(faces[1]);
    adj[faces[1]].push_back(faces[0]);
  }
  out.face_patch.assign(nf, -1);
  std::vector<int> stack;
  for (int seed = 0; seed < nf; ++seed) {
    if (out.face_patch[seed] >= 0) continue;
    const int id = out.num_patches++;
    out.face_patch[seed] = id;
    stack.push_back(seed);
    while (!stack.empty()) {
      int f = stack.back();
      stack.pop_back();
      for (int g : adj[f])
        if (out.face_patch[g] < 0) {
          out.face_patch[g] = id;
          stack.push_back(g);
        }
    }
  }

  // Chain sharp edges: from each corner along each unused sharp edge until the next corner.
  std::vector<std::vector<int>> nbrs(nv);
  for (auto [a, b] : features.sharp_edges) {
    nbrs[a].push_back(b);
    nbrs[b].push_back(a);
  }
  std::vector<char> is_corner(nv, 0);
  for (int c : features.corners) is_corner[c] = 1;
  std::set<std::pair<int, int>> used;
  auto key = [](int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); };
  auto walk = [&](int start, int next) {
    std::vector<int> chain{start};
    int prev = start, cur = next;
    used.insert(key(prev, cur));
    while (true) {
      chain.push_back(cur);
      if (cur == start || is_corner[cur]) break;
      int step = -1;
      for (int w : nbrs[cur])
        if (!used.count(key(cur, w))) {
          step = w;
          break;
        }
      if (step < 0) break;
      used.insert(key(cur, step));
      prev = cur;
      cur = step;
    }
    out.polylines.push_back(std::move(chain));
  };
  for (int c : features.corners)
    for (int w : nbrs[c])
      if (!used.count(key(c, w))) walk(c, w);
  for (auto [a, b] : features.sharp_edges)  // what is left are closed loops without corners
    if (!used.count({a, b})) walk(a, b);
  return out;
}

}  // namespace mm
