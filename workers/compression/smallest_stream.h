// The stream a compress run writes: among the control polyhedra that met the tolerance, each at
// the fewest quantisation bits whose decoded surface still meets it (with its nearest grid
// values, or with grid values chosen for the surface: compression/grid_descent.h), the smallest; then
// the chosen polyhedron is numbered from the start vertex that codes smallest, and
// rate-distortion snapping (CodecParams::snap_cells) spends the tolerance the chosen surface
// leaves unused on bytes. Every candidate stream is decoded, subdivided and checked against the
// tolerance by decoded_within, which answers exactly as decoded_distance (the measurement
// `meshmark compare` reports) would compare, without its numbers; the stream written is then
// measured whole for its report: nothing is accepted on an estimate. Deterministic for the same
// inputs.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "meshio/mesh.h"
#include "quality/surface_distance.h"

namespace mm {

struct StreamSearch {
  double tolerance = 0.005;    // symmetric Hausdorff distance / the part's diagonal
  double rms_tolerance = 0;    // RMS distance / diagonal; 0: not bounded
  int levels = 3;              // the level the stream is decoded and measured at
  int bits = 0;                // > 0: these bits only, no snapping
  // false when the fit itself missed the tolerance: the conservative bits only.
  bool fit_met = true;
  // false: every coordinate at its nearest grid value (no snapping, no grid descent).
  bool snap = true;
  // true (compress --fast): the first polyhedron only, at the fewest bits whose nearest grid
  // values meet the tolerances (from 6 up, as the search starts), in its own numbering: no grid
  // descent, snapping, other polyhedra or numberings. The stream is checked (decoded_within, the
  // whole measurement's answer), not measured: the numbers cost about 0.3 s on a 20k-triangle
  // part, four times the check. ChosenStream::measured is false unless an RMS bound needs the
  // numbers or nothing meets the tolerances (the miss is then measured, for its report).
  bool quick = false;
  std::map<std::string, std::string> metadata;  // written into every candidate stream
};

struct ChosenStream {
  std::vector<std::uint8_t> bytes;
  SurfaceDistance distance;       // of the decoded `bytes`
  int bits = 0;
  // Index into the polyhedra given. The stream may number its vertices from another start
  // vertex than the polyhedron does (in_traversal_order, codec/stream.h): the same surface.
  int polyhedron = 0;
  bool snapped = false;
  // The grid values were chosen for the surface (descended_on_grid, compression/grid_descent.h):
  // the polyhedron missed the tolerance at these bits with its nearest grid values.
  bool descended = false;
  std::size_t unsnapped_bytes = 0;  // the chosen polyhedron's plain stream (cheapest numbering)
  bool meets = false;             // distance within both tolerances
  bool measured = true;           // false: `distance` was not measured (StreamSearch::quick)
};

// Fewest bits whose worst rounding error (half a grid step on each axis) stays below a fifth of
// the tolerance, on the grid encode() uses for `control`: the most the search tries.
int conservative_bits(const Mesh& control, double tolerance);

// `polyhedra` fewest vertices first, in the part's units (compress()'s candidates, or its one
// control mesh when none met the tolerance). Bits from 6 (kMinQuantBits) up to
// conservative_bits; a polyhedron whose stream at some bits is already no smaller than the best
// so far is not measured further. When nothing meets the tolerances, the first polyhedron at
// its conservative bits is returned (meets = false). `name` names the streams in errors.
ChosenStream smallest_stream(const Mesh& part, const std::vector<const Mesh*>& polyhedra, const StreamSearch& search,
                             const std::string& name);
// The same against a part a caller has measured before (its fit's verify), with its samples and
// tree; measured with its SamplingParams (the Mesh overload: the defaults, `meshmark compare`'s).
ChosenStream smallest_stream(const MeasuredSurface& part, const std::vector<const Mesh*>& polyhedra,
                             const StreamSearch& search, const std::string& name);

}  // namespace mm
