// What a detection's evidence package shows a reader: plain words for its numbers, pictures of the
// part, the issued copy and the suspect, and the self-contained HTML page that holds them.
//
// Everything here is a pure function of what it is handed (the package's statement predicate,
// meshes, numbers): the same inputs give the same bytes, so a package can be rebuilt and compared.
// The page reads the predicate generically (each copy's statistic by name, its -log10 p), so it
// documents whatever detector made the detection.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshio/mesh.h"

namespace mm::jobs {

// "less than once in 10^40 trials" for -log10 p = 40.3; "about 3 times in 100 trials" for 1.5.
std::string odds_in_words(double neg_log10_p);

struct ReportPicture {
  std::string id;       // file-safe name, e.g. "side-by-side"
  std::string title;    // heading on the page
  std::string caption;  // what the reader sees and how to read it
  std::vector<std::uint8_t> png;
};

// The suspect brought into the original's frame by a similarity (uniform scale, rotation,
// translation) fitted by ICP to the original surface, so pictures share one view; and its RMS.
struct RegisteredSuspect {
  Mesh mesh;
  double rms = 0;  // trimmed RMS closest-point distance after alignment
};
RegisteredSuspect register_to_original(const Mesh& original, const Mesh& suspect);

// The original, the issued copy (when at hand, else the slot says so) and the registered suspect
// from one camera, side by side.
ReportPicture side_by_side_picture(const Mesh& original, const Mesh* issued_copy, const Mesh& suspect_registered);
// The registered suspect coloured by each face's distance to the original surface (blue 0 to red
// at the largest, the scale given in the caption as a share of the original's diagonal).
ReportPicture distance_picture(const Mesh& original, const Mesh& suspect_registered);
// The statistic against its null: a standard normal density of z (the calibrated null of the
// sign count: (correlation - null mean) / null sd) with the observed copy's z and every other
// copy's z marked.
ReportPicture null_picture(double observed_z, const std::vector<double>& other_z, const std::string& copy_label);
// -log10 of each copy's corrected p, with the decision threshold drawn.
ReportPicture copy_scores_picture(const std::vector<std::pair<std::string, double>>& copies_neg_log10_p,
                                  double threshold_neg_log10_p);

// The page: verdict in plain words first, then pictures, per-copy scores, the method's measured
// error rate, the chain of records, the hashes and every parameter. Pictures are embedded as data
// URIs, so the page is one file that opens anywhere.
std::string evidence_html(const nlohmann::json& predicate, const std::vector<ReportPicture>& pictures);

}  // namespace mm::jobs
