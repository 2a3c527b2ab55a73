// Seeded attacks on a mesh for demos and robustness tests (`meshmark attack`). Amplitudes and
// shifts are relative to the mesh's largest bounding-box side (unit-box units), so the same
// numbers mean the same damage on a part in millimetres or in metres.
#pragma once
#include <Eigen/Core>
#include <cstdint>

#include "meshio/mesh.h"

namespace mm::cli {

// Adds independent uniform noise in [-amplitude, amplitude] x largest side to every coordinate.
// The generator is std::mt19937_64 mapped to doubles by hand (53 high bits), not
// std::uniform_real_distribution, whose output differs between standard libraries: the same seed
// gives the same file everywhere.
void add_uniform_noise(Points& points, double amplitude, std::uint64_t seed);

// p -> scale * Rz(rotate_degrees) * p + shift x largest side (side measured before the move).
void apply_similarity(Points& points, double scale, double rotate_degrees, const Eigen::Vector3d& shift);

// Splits every triangle into four and every quad into four at its edges' midpoints (and the quad's
// centre), `levels` times: the same surface, four times the faces per level, no vertex moved. A
// re-tessellation a leaker may apply, and the benchmark's way to a larger part of the same shape
// (abc5's 5,080 triangles to 20,320). Subdivision with every edge a crease and every vertex a
// corner (subdivision/subdivide.h), so its errors are subdivide()'s; the result has no tags.
Mesh subdivide_linear(Mesh mesh, int levels);

// Largest side of the bounding box (0 for an empty or single-point set).
double largest_side(const Points& points);

}  // namespace mm::cli
