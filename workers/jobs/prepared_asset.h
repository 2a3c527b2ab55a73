// The per-asset work a protect job does once and every customer copy reuses: the control
// polyhedron the watermark lives in, the normalisation that maps the part into the unit box, and
// the exact spectral basis of the polyhedron's connectivity (persisted, because recomputing it at
// detection time could pick different eigenvectors inside repeated eigenvalues).
//
// Today the control polyhedron is the normalised input mesh itself; when the compressor lands,
// prepare_asset() calls it and everything downstream stays the same (copies are then the
// subdivided watermarked polyhedron).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "meshio/mesh.h"
#include "meshio/normalize.h"
#include "spectral/spectral_basis.h"

namespace mm::jobs {

struct PrepareParams {
  // The basis is dense (n x n doubles), so its size is capped before anything is allocated.
  int max_vertices = 4000;  // <= kMaxBasisVertices
  std::string key() const;  // canonical cache key of the preparation method
};

// Cheap descriptor used to find the asset a suspect file came from when its hash is unknown.
struct ShapeSignature {
  int vertices = 0;
  int faces = 0;
  double box[3] = {0, 0, 0};     // bounding box sides divided by the largest side
  double moments[3] = {0, 0, 0}; // sorted eigenvalues of the normalised point covariance
  std::string to_json() const;
  static ShapeSignature from_json(const std::string& json);  // InputError on malformed
};
ShapeSignature shape_signature(const Mesh& mesh);
// 0 for identical shapes; grows with box/moment differences and relative vertex-count change.
double signature_distance(const ShapeSignature& a, const ShapeSignature& b);

struct PreparedAsset {
  Mesh control;                 // normalised into the unit box
  Normalization normalization;  // original units -> unit box
  SpectralBasis basis;          // of control's connectivity
  ShapeSignature signature;     // of the original
};

// Throws InputError(source, ...) if the mesh is unusable (too many vertices, degenerate box).
PreparedAsset prepare_asset(const Mesh& original, const PrepareParams& params,
                            const std::string& source);

// Exact little-endian serialisation (doubles bit for bit); the basis uses serialize_basis(). Decoding checks every size against the
// buffer and throws InputError(source, ...) on anything inconsistent.
std::vector<std::uint8_t> encode_polyhedron(const PreparedAsset& asset);
PreparedAsset decode_prepared(const std::vector<std::uint8_t>& polyhedron,
                              const std::vector<std::uint8_t>& basis, const std::string& source);

}  // namespace mm::jobs
