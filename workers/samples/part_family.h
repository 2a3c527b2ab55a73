// Families of sample parts like the ones a PDM vault holds: each sample part with seeded
// dimensions, all in millimetres and in the same frame (the origin at a corner or on the axis),
// so that many members share whole regions (plates with the same cell, thickness and holes).
// That is the hard case for finding the part a cropped copy came from among thousands.
#pragma once
#include <cstdint>
#include <string>

#include "samples/samples.h"

namespace mm::samples {

// Member `variant` of the family of sample part `name` ("chamfered_block", "plate_with_holes",
// "flanged_cylinder"); variant 0 is the part with its default dimensions. Deterministic on
// every platform (its own integer generator, no std distributions). Throws
// std::invalid_argument for an unknown name.
SamplePart sample_variant(const std::string& name, std::uint64_t variant);

}  // namespace mm::samples
