// Deterministic CAD-like sample parts for demos and tests when no real meshes are at hand:
// closed, manifold, watertight, outward oriented, with sharp features.
#pragma once
#include <string>
#include <vector>

#include "samples/chamfered_block.h"
#include "samples/flanged_cylinder.h"
#include "samples/plate_with_holes.h"

namespace mm::samples {

struct SamplePart {
  std::string name;  // "chamfered_block", "plate_with_holes", "flanged_cylinder"
  Mesh mesh;
};

// The three parts with their default dimensions, in this order.
std::vector<SamplePart> sample_parts();

}  // namespace mm::samples
