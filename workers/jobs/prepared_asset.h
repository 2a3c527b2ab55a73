// The per-asset work a protect job does once and every customer copy reuses: the control
// polyhedron the watermark lives in, the normalisation that maps the part into the unit box, and
// the exact spectral basis of the polyhedron's connectivity (persisted, because recomputing it at
// detection time could pick different eigenvectors inside repeated eigenvalues).
//
// The control polyhedron is the compressor's (fitting/compress.h): copies are the watermarked
// polyhedron as a .mmc stream and that stream decoded (subdivided at `levels`).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "fitting/compress.h"
#include "geometry/surface_footprint.h"
#include "meshio/mesh.h"
#include "meshio/normalize.h"
#include "spectral/spectral_basis.h"

namespace mm::jobs {

struct PrepareParams {
  CompressOptions compression;  // every field changes the result, so all are in key()
  // When the fit at compression.angle_degrees misses the tolerance, the smaller of these angles
  // are tried in turn (one fit per new crease network) until one meets it; the first that does
  // is kept, else the closest (fallback_crease_angles(), fitting/compress.h, says why). Empty:
  // the configured angle only. In key().
  std::vector<double> fallback_angles = fallback_crease_angles();
  // The basis costs memory and time with the control vertex count (spectral_basis.h): a control
  // budget above this is refused before compressing, and so is a control polyhedron that ends up
  // larger; a min_mark_vertices step that would pass it is not taken. Not in key().
  int max_control_vertices = 4000;  // <= kMaxBasisVertices
  // A smaller control polyhedron is refined by whole subdivision steps until it has at least
  // this many vertices (the same limit surface, decoded one level less per step), unless a step
  // would pass max_control_vertices: the mark then spreads over more coefficients, which raises
  // the p-value floor a small part's few coefficients set (3n coefficients for n vertices).
  // 0: never. In key() when not 0.
  int min_mark_vertices = 200;
  // A copy decodes the polyhedron at compression.levels; when that gives more triangles than
  // this, at the highest level that does not, if the copy there still meets the tolerance by the
  // dense measurement; else the part is refused. A dense polyhedron (a tight tolerance) would
  // otherwise issue copies hundreds of times the part's size that detection refuses by the same
  // limit (the daemon's max_triangles). 0: no limit. In key() when not 0.
  long long max_copy_triangles = 0;
  std::string key() const;  // canonical cache key of the preparation method and its options
};

// Cheap descriptor used to find the asset a suspect file came from when its hash is unknown.
// Computed on the surface (area-weighted), not on the vertices, so a decoded copy with 20x the
// vertices, a remeshed or a subdivided copy have about the same signature as the original; and
// in the principal frame, so a rescaled, rotated or shifted copy has the same signature.
struct ShapeSignature {
  int version = 2;               // from_json refuses any other
  int vertices = 0;              // informative only
  int faces = 0;                 // informative only
  double box[3] = {0, 0, 0};     // extents along the principal axes / the largest
  double moments[3] = {0, 0, 0}; // ascending eigenvalues of the area-weighted surface covariance / trace
  std::string to_json() const;
  static ShapeSignature from_json(const std::string& json);  // InputError on malformed
};
ShapeSignature shape_signature(const Mesh& mesh);
// 0 for identical shapes; grows with box and moment differences. Scale, shift and tessellation
// and rotation invariant.
double signature_distance(const ShapeSignature& a, const ShapeSignature& b);

struct PreparedAsset {
  Mesh control;                 // normalised into the unit box; creases and corners tagged
  Normalization normalization;  // original units -> unit box
  SpectralBasis basis;          // of control's connectivity
  ShapeSignature signature;     // of the original
  SurfaceFootprint footprint;   // of the original, in its units (prepare_asset only; not serialised)
  int levels = 0;               // subdivision levels of the decoded copy
  int refinements = 0;          // steps taken for min_mark_vertices (prepare_asset only; not serialised)
  CompressResult compression;   // statistics of the fit (prepare_asset only; not serialised)
};

// Refines `control` by whole subdivision steps while it has fewer than min_vertices vertices
// and the next step stays within max_vertices; returns the steps taken. Creases and corners are
// carried, so the limit surface is unchanged.
int refine_for_mark(Mesh& control, int min_vertices, int max_vertices);

// Compresses the part (throws InputError(source, reason) when it cannot be compressed, the
// control polyhedron exceeds the basis cap or no level within max_copy_triangles meets the
// tolerance; std::invalid_argument for a budget above the cap), chooses the copy's level,
// normalises the control polyhedron and computes its exact spectral basis.
PreparedAsset prepare_asset(const Mesh& original, const PrepareParams& params,
                            const std::string& source);

// Exact little-endian serialisation (doubles bit for bit; format MMPOLY02); the basis uses
// serialize_basis().
// Decoding checks every size and index against the buffer and throws InputError(source, ...) on
// anything inconsistent.
std::vector<std::uint8_t> encode_polyhedron(const PreparedAsset& asset);
PreparedAsset decode_prepared(const std::vector<std::uint8_t>& polyhedron,
                              const std::vector<std::uint8_t>& basis, const std::string& source);

}  // namespace mm::jobs
