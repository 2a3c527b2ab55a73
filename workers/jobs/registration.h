// Bringing a suspect mesh into the vertex order and frame of an asset's control polyhedron, so
// non-blind extraction can compare them vertex by vertex.
#pragma once
#include <string>

#include "jobs/prepared_asset.h"

namespace mm::jobs {

struct Registration {
  Points points;          // control.num_vertices() x 3, in the control's normalised frame
  std::string method;     // "identity" (same connectivity) or "nearest-neighbour"
  double rms = 0;         // residual after alignment, in unit-box units
  double matched_fraction = 0;  // distinct suspect vertices used / control vertices
};

// Same vertex count and faces: vertices correspond by index. Otherwise each control vertex takes
// its nearest suspect vertex after bounding-box normalisation, refined by a few iterations of
// nearest-neighbour + similarity (Umeyama) alignment. Either way a final similarity transform
// maps the suspect into the control's frame, undoing a rescale or shift of the leaked file.
Registration register_suspect(const PreparedAsset& asset, const Mesh& suspect);

}  // namespace mm::jobs
