// How far each coordinate of a control polyhedron may move before its decoded surface leaves
// the tolerance, estimated from the surface's local error and orientation. An encoder that may
// move coordinates a little to save bytes (rate-distortion snapping, CodecParams::snap_cells)
// moves them where the surface is well inside the tolerance, and along the directions the
// surface does not depend on there (a vertex inside a flat face region moves along the face for
// free), and leaves alone the coordinates whose surface already uses the tolerance up.
#pragma once
#include <limits>
#include <vector>

#include "meshio/mesh.h"
#include "quality/surface_distance.h"

namespace mm {

// `control` subdivided `levels` times (as decoded_distance does). Each refined vertex r gets an
// error e_r: the larger of its own distance to the part and the distances of the part's
// samples (params: count, seed, vertices) whose closest point on the refined surface lies in a
// triangle it is a corner of; and per axis a, m_ra = the largest |normal_a| of its triangles.
// Moving control vertex v by t_a along each axis moves r by S(r, v) t (S the subdivision
// operator, rows summing to 1), which changes its distance to the part by at most about
// sum_a m_ra t_a. So coordinate (v, a) gets slack
//   min over r with S(r, v) != 0 and m_ra > 1e-3 of (tolerance - e_r) / (m_rx + m_ry + m_rz),
// which keeps every refined vertex within the tolerance to first order even when all control
// vertices move at once (never negative; 1e30 when no refined vertex depends on that axis).
// Result: 3 values per control vertex (x, y, z), absolute units. An estimate, not a
// measurement: the caller measures what it builds from it. Throws InputError as
// build_subdivision and sample_surface do.
std::vector<double> coordinate_slack(const Mesh& part, const Mesh& control, int levels, double tolerance,
                                     const SamplingParams& params = {});
// The same against a part measured once (quality/surface_distance.h): its tree, and its samples
// where `params` are its own. A caller that only asks which slacks are at most `exact_up_to` gets
// those as above and the others only as larger: a refined vertex or sample certainly nearer the
// part than tolerance - 3 exact_up_to (TriangleDistanceTree::within) cannot set such a slack and
// is not measured (a repair of a snapped stream asks about slack 0 or a quarter of a grid step:
// most of the 200,000 samples then cost a tolerance check's query instead of a closest point).
std::vector<double> coordinate_slack(const MeasuredSurface& part, const Mesh& control, int levels, double tolerance,
                                     const SamplingParams& params = {},
                                     double exact_up_to = std::numeric_limits<double>::infinity());

}  // namespace mm
