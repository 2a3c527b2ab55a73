// Where a part's surface lies, in the part's own coordinates: its bounding box and the cells of a
// coarse grid over that box that the surface passes through. A leaked copy is issued in the
// part's units, so a piece cut from it (a crop) lies in those same cells, while its shape
// signature (whole-part moments and extents) no longer resembles the part's. Detection uses the
// footprint to find the asset a partial suspect came from among many (jobs/detect_suspect).
#pragma once
#include <Eigen/Core>
#include <string>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct SurfaceFootprint {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero();  // grid origin: half a cell below the surface's box
  double cell = 0;                               // cube cell side; 0: empty footprint
  int dims[3] = {0, 0, 0};                       // cells along x, y, z
  std::vector<bool> occupied;                    // x fastest, then y, then z

  bool empty() const { return cell <= 0; }
  std::string to_json() const;                            // the occupied cells as hex bytes
  static SurfaceFootprint from_json(const std::string&);  // InputError("surface footprint", ...)
};

// Cells of side (largest bounding-box side) / cells_along_largest that some face touches; every
// face is sampled on a barycentric grid finer than half a cell, so large flat facets of a
// tessellated CAD part mark every cell they cross. Deterministic.
SurfaceFootprint surface_footprint(const Mesh& mesh, int cells_along_largest = 32);

// What a suspect is tested with: its vertices and face centroids (at most max_points of each,
// evenly strided) and their bounding box, made once for testing many footprints.
struct FootprintProbe {
  Points points;
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
};
FootprintProbe footprint_probe(const Mesh& suspect, int max_points = 2000);

// Share of the probe's points lying in an occupied cell or, with reach 1, one of its 26
// neighbours, which absorbs noise and a watermark up to a cell (reach 0: the point's own cell,
// which ranks assets that all hold a suspect). 0 for an empty footprint or probe, when the
// probe's box reaches more than a cell outside the footprint's, and when the probe spans fewer
// than min_cells cells along its longest side: a few cells of a large part hold any small one.
double covered_fraction(const SurfaceFootprint& footprint, const FootprintProbe& probe, int reach = 1,
                        int min_cells = 8);

// How alike the part's surface and the suspect's are over the suspect's cell range: the cells
// the suspect's faces touch (sampled as surface_footprint samples the part's) against the part's
// cells there, |both| / |either|. A crop of the part scores near 1 (less where a mark or noise
// moves its surface across a cell boundary); another part that also holds the crop but has more
// surface in that region (other holes, a wall) scores less. 0 for an empty footprint or suspect.
// Parts identical over the region tie: only the mark tells them apart.
double region_agreement(const SurfaceFootprint& footprint, const Mesh& suspect);

}  // namespace mm
