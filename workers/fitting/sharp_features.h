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
  // A crease vertex is a corner if the crease turns more than this. 70 rather than 50: the
  // zigzag crease lines of remeshed parts turned into hundreds of locked corners (rocker: 78
  // turn corners at 50, 16 at 70; fandisk and bracket-3 keep the same corners).
  double corner_turn_degrees = 70.0;
  // Crease fragments shorter than this many edges that end in the open (isolated bits, or spurs
  // off a longer crease) are noise from remeshing, not part edges: they are dropped. Open
  // boundary edges are always kept. 0 keeps everything. 6 rather than 3 halves the dangling
  // crease ends of the JIGSAW parts (rocker 137 -> 48) and changes nothing on fandisk,
  // bracket-3 and the ABC parts.
  int min_crease_edges = 6;
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

// Whether two feature sets of one mesh are the same crease network (sharp edges and corners):
// compress() gives the same result for both, so a caller trying several angles fits it once.
bool same_crease_network(const Features& a, const Features& b);

}  // namespace mm
