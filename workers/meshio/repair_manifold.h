// Making a polygon soup a manifold, consistently oriented mesh WITHOUT dropping any face, so it
// loads into a halfedge structure (OpenMesh rejects "complex edge"/"complex vertex" faces).
//
// An edge is kept (its two faces stay glued) only when exactly two faces use it in opposite
// directions. Every other edge - used by three or more faces, or by two faces in the same
// direction - is cut. Around each vertex the faces are then grouped into fans glued by kept
// edges; a vertex with several fans (bowtie, touching solids, cut edges) gets one copy per
// extra fan. Copies are appended after the original vertices, so original indices (and their
// order, which the watermark depends on) are unchanged. In the rare case where cut faces still
// share both endpoint copies, those faces get private copies of the edge's endpoints.
#pragma once
#include <string>
#include <vector>

#include "meshio/mesh.h"
#include "meshio/read_mesh.h"

namespace mm {

struct ManifoldRepair {
  int complex_edges = 0;         // edges of the input with > 2 faces or same-direction faces
  int complex_vertices = 0;      // input vertices whose faces formed more than one fan
  int vertices_duplicated = 0;   // vertices appended
  std::vector<int> original_vertex;  // for every output vertex, the input vertex it copies
};

// What is wrong with a mesh, without changing it (both zero means manifold and oriented).
ManifoldRepair check_manifold(const Mesh& mesh);

// Splits vertices until the mesh is manifold and consistently oriented across kept edges.
// Faces, their order and their vertex order are unchanged apart from renumbered copies.
// Requires faces with >= 3 distinct, in-range vertices (what read_mesh returns).
ManifoldRepair repair_manifold(Mesh& mesh);

// read_mesh followed by repair_manifold: what the pipeline uses for its halfedge algorithms.
Mesh read_mesh_manifold(const std::string& path, ReadReport* report = nullptr,
                        ManifoldRepair* repair = nullptr);

}  // namespace mm
