// The matched score's evidence read on a suspect surface instead of recovered control points.
//
// A remeshed, simplified or re-extracted copy keeps the mark's normal component on its surface
// but no vertex correspondence; recovering control points from it leaves the unobservable
// tangential directions to a weak prior, and that noise drowns the coefficients. Here the
// suspect's normal offsets d_i from the original surface (registration/surface_offsets.h) are
// regressed directly on the mark's own shapes: coefficient j = (k, axis) moves sample i by
// n_axis(i) (R W_k)_i g_j, with R the samples' rows over the control points, W_k the k-th Kirchhoff
// eigenvector and g_j the coefficient's embedding move (the same for every copy; only its sign
// is the key's). Ridge regression with a unit prior on each gain beta_j and free nuisance terms
// (what a small error of the alignment explains), the ridge equal to the residual variance (the
// posterior mean), refitted three times. u_j = beta_j times the move's direction, scored by
// matched_score(): for a suspect made without a copy's key, its signs are independent of u, so
// Hoeffding's bound holds exactly whatever the fit did.
#pragma once
#include <Eigen/Sparse>

#include "watermark/matched_score.h"

namespace mm {

// Only the lowest-frequency coefficients are fitted (at most this many; the rest get u_j = 0):
// attacks that change connectivity keep little of the highest frequencies, and the fit's cost
// grows with the square of the coefficients (not with the samples: every suspect vertex is used).
constexpr int kSurfaceEvidenceCoefficients = 1200;

// rows: m x n (n = basis.num_vertices()), normals m x 3, offsets m, all in the frame of
// `original` (the unmarked control points the basis was computed on); nuisance m x k (k < m,
// may be empty): offset patterns fitted freely and not counted as the mark. Throws
// std::invalid_argument for mismatched sizes or message_bits <= 0.
CoefficientEvidence surface_evidence(const SpectralBasis& basis, const Points& original,
                                     const Eigen::SparseMatrix<double>& rows, const Points& normals,
                                     const Eigen::VectorXd& offsets, const Eigen::MatrixXd& nuisance,
                                     int message_bits, const EmbedParams& params);

}  // namespace mm
