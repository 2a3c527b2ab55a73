// Sharp features of a CAD mesh: the edges where two faces meet at a dihedral angle above a
// threshold (plus open-boundary and non-manifold edges), and the corner vertices where the
// crease network branches, ends or turns sharply. These become the infinitely sharp creases and
// corners of the subdivision control polyhedron, so the decoded surface keeps the part's edges.
#pragma once
#include <set>
#include <utility>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct FeatureOptions {
  double angle_degrees = 35.0;        // an edge is sharp if its faces' normals differ more than this
  double corner_turn_degrees = 50.0;  // a crease vertex is a corner if the crease turns more than this
  // Crease fragments shorter than this many edges that end in the open (isolated bits, or spurs
  // off a longer crease) are noise from remeshing, not part edges: they are dropped. Open
  // boundary edges are always kept. 0 keeps everything.
  int min_crease_edges = 3;
};

struct Features {
  std::vector<std::pair<int, int>> sharp_edges;  // (i < j), sorted; includes open-boundary edges
  std::vector<int> corners;                      // sorted vertex indices
  std::vector<int> sharp_valence;                // per vertex: number of sharp edges at it
  int boundary_edges = 0;                        // edges with exactly one face
  int nonmanifold_edges = 0;                     // edges with three or more faces (marked sharp)
  std::set<std::pair<int, int>> boundary_set;    // the open-boundary edges
};

// Works on any polygon mesh, any number of components, any scale (angles only).
Features detect_features(const Mesh& mesh, const FeatureOptions& options = {});

}  // namespace mm
