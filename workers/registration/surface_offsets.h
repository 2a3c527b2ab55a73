// Signed offsets of a suspect's vertices from the original refined surface, along its normals:
// what a surface test of the mark reads (watermark/surface_evidence.h) without recovering the
// control points. A remeshed, simplified or re-extracted copy keeps its vertices on the marked
// surface, so each offset is the mark's normal component there plus the attack's error; vertices
// rather than area samples, because a coarse remesh's faces cut chords through curved regions.
#pragma once
#include <Eigen/Sparse>
#include <vector>

#include "meshio/mesh.h"
#include "registration/align_similarity.h"
#include "registration/resynchronize.h"

namespace mm {

struct SurfaceOffsets {
  // m x n: sample i's closest point on the original surface as a combination of control points
  // (barycentric weights times the refinement operator's rows), so a control displacement D moves
  // it by rows * D.
  Eigen::SparseMatrix<double> rows;
  Points normals;           // m x 3: unit normal of the original triangle under sample i
  Eigen::VectorXd offsets;  // m: (suspect point - closest point) . normal, in the control's frame
  // m x 7: the offsets a small error of the alignment makes, which are not the mark's: n
  // (translation), p x n (rotation), n . p (scale), p the closest point (the constant, an
  // inflation, is surface_evidence's own).
  Eigen::MatrixXd nuisance;
  bool empty() const { return offsets.size() == 0; }
};

constexpr int kSurfaceOffsetSamples = 100000;
constexpr double kSurfaceOffsetDistance = 0.02;

// Suspect vertices (evenly strided, at most max_samples: the test's power grows with the root of
// the vertices a noisy copy keeps, and its cost barely) mapped by to_control_frame and paired
// with their closest points on the context's fit surface; those farther than max_distance x the
// diagonal are left out (where the suspect is not the part).
SurfaceOffsets surface_offsets(const ResyncContext& context, const Mesh& suspect, const Similarity& to_control_frame,
                               int max_samples = kSurfaceOffsetSamples, double max_distance = kSurfaceOffsetDistance);

// The two readings a detection scores, in this order: the suspect where it lies in the asset's
// frame, with no alignment terms (a copy leaked unmoved keeps its mark whole there, also its
// lowest frequencies, which on a disc or a plate look like a small tilt or scale and which the
// alignment and its terms would take: abc7 remeshed, -log10 p 0 aligned, 33-94 in frame), and in
// the aligned pose with the alignment's error terms (a copy that was moved).
constexpr const char* kSurfaceReadings[] = {"asset frame", "aligned"};
// The first reading alone: surface_offsets() unmoved, with no alignment terms.
SurfaceOffsets surface_in_frame(const ResyncContext& context, const Mesh& suspect);
// Both; the second pairs each vertex starting from its first answer (the same pairs but for
// ties, in a fraction of the time).
std::vector<SurfaceOffsets> surface_readings(const ResyncContext& context, const Mesh& suspect,
                                             const Similarity& to_control_frame);

}  // namespace mm
