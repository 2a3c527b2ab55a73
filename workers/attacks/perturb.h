// Attacks that move vertices and keep the mesh's connectivity and vertex order: what a leaker's
// mesh tool does to a copy without remeshing it. Seeded and platform-independent: the same
// arguments give the same coordinates everywhere. Amplitudes are relative to the largest side of
// the mesh's bounding box, so the same numbers mean the same damage in millimetres or metres.
// The attacks of Wang, Lavoue, Denis and Baskurt's benchmark ("A benchmark for 3D mesh
// watermarking", SMI 2010) that keep connectivity: noise, quantisation, smoothing, similarity.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "meshio/mesh.h"

namespace mm::attacks {

// Largest side of the bounding box (0 for an empty or single-point set).
double largest_side(const Points& points);

// Adds independent uniform noise in [-amplitude, amplitude] x largest side to every coordinate.
// std::mt19937_64 mapped to doubles by hand (53 high bits), not std::uniform_real_distribution,
// whose output differs between standard libraries.
void add_uniform_noise(Points& points, double amplitude, std::uint64_t seed);

// p -> scale * Rz(rotate_degrees) * p + shift x largest side (side measured before the move).
void apply_similarity(Points& points, double scale, double rotate_degrees, const Eigen::Vector3d& shift);

// Rounds every coordinate to the centre of its cell on a grid of 2^bits cells along the
// largest side of the bounding box (as a format or a tool storing `bits`-bit integers does).
// bits in [1, 30].
void quantize_coordinates(Points& points, int bits);

// Laplacian smoothing with the umbrella operator: `iterations` times, every vertex moves by
// lambda times the difference between its edge neighbours' mean and itself (all at once, Jacobi
// style). Open-boundary vertices are smoothed like the others. lambda in (0, 1].
void smooth_laplacian(Mesh& mesh, int iterations, double lambda);

// The same smoothing, one step at a time, over a connectivity built once (a model of the attack
// evaluates many steps of it).
class UmbrellaSmoother {
 public:
  explicit UmbrellaSmoother(const Mesh& connectivity);
  // points <- points + lambda (neighbour mean - points), every vertex at once.
  void step(Points& points, double lambda) const;

 private:
  std::vector<int> offsets_, neighbours_;
};

// Renumbers vertices and reorders faces at random (each face keeps its orientation, and starts
// at a random one of its vertices): the same surface in another file order.
void shuffle_order(Mesh& mesh, std::uint64_t seed);

// The vertex-wise mean of several copies with the same connectivity (a collusion): the faces of
// the first. Throws InputError(names[i], reason) when a copy's vertex or face count differs.
Mesh average_copies(const std::vector<Mesh>& copies, const std::vector<std::string>& names);

}  // namespace mm::attacks
