// Cropping: a leaker keeps part of a part. The faces whose centroid lies within the first
// `keep_fraction` of the bounding box along its longest axis are kept (from its low end, or its
// high end with `from_high`), with the vertices they use, in their original relative order.
#pragma once
#include "meshio/mesh.h"

namespace mm::attacks {

// keep_fraction in (0, 1]. Throws InputError("crop", reason) when no face is left.
Mesh crop_along_longest_axis(const Mesh& mesh, double keep_fraction, bool from_high = false);

}  // namespace mm::attacks
