// A leaker's smoothing, modelled from the original itself. Laplacian smoothing shrinks a copy
// and flattens its features by far more than the mark moves it, the same way for every copy; what
// it leaves of the mark is the difference between the smoothed copy and the original smoothed
// the same way. fit_smoothing() finds the umbrella smoothing (workers/attacks) of the original's
// refined surface that best explains an in-order suspect; the caller takes that smoothing's change
// of the original out of the suspect before solving for the control points. It uses the original
// and the suspect only, never a key, so detection's p-values stay exact.
#pragma once
#include <string>

#include "meshio/mesh.h"
#include "registration/align_similarity.h"

namespace mm {

struct SmoothingModel {
  double lambda = 0;
  int iterations = 0;            // 0: no smoothing explains the suspect better than none
  double residual_rms = 0;       // RMS of suspect - smoothed original (per vertex, 3D)
  double unsmoothed_rms = 0;     // RMS of suspect - original
  Points smoothed;               // the original smoothed by the model (empty when iterations is 0)
  Similarity to_original;        // maps the suspect onto `smoothed` (or the original, for none)
  std::string describe() const;  // "umbrella smoothing, lambda 0.5 x 10", or "" for none
};

// `connectivity`: the refined original's faces; `original`, `suspect`: its points and the
// suspect's, in the same numbering. With `align`, each candidate is compared after the
// similarity that best maps the suspect onto it (smoothing shrinks a part, and a similarity fitted
// to the unsmoothed original takes part of that in); else in the frames given. Tries lambda 0.25,
// 0.5, 0.75 and 1 up to `max_iterations` steps each; a model is kept when it explains the suspect
// at least twice as well as no smoothing.
SmoothingModel fit_smoothing(const Mesh& connectivity, const Points& original, const Points& suspect, bool align,
                             int max_iterations = 40);

}  // namespace mm
