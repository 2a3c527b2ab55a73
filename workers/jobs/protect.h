// Protect: one customer's watermarked copy of a prepared asset, as the files a customer receives.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "jobs/prepared_asset.h"
#include "watermark/watermark.h"

namespace mm::jobs {

struct WatermarkSettings {
  EmbedParams params;
  int message_bits = 32;  // payload width; 8..64
};

// Embeds payload_to_bits(payload) with the customer's key and the copy's nonce into the control
// polyhedron and returns the watermarked polyhedron in the part's own units (same vertex order,
// faces, creases and corners as asset.control). Pure: no I/O; the caller writes and records it.
Mesh make_copy(const PreparedAsset& asset, const Key& key, const Nonce& nonce,
               std::uint64_t payload, const WatermarkSettings& settings);

// Spectral coefficients per payload bit, floor(3n / bits) for n control vertices (the paper's r).
int coefficients_per_bit(const PreparedAsset& asset, int message_bits);
// Below this spread a copy leaked unmodified may not be attributed: abc7's 24 control vertices
// spread a 32-bit payload over 2 a bit and reached a corrected p of only 1e-5.9 to 1e-7 with six
// customers; at 16 bits, 4 a bit, every run passed (E2E.CopiesLeakedAsIssuedAreAttributed).
constexpr int kWeakSpread = 4;
// The protect job's warning when the spread is under kWeakSpread; "" otherwise.
std::string weak_spread_warning(const std::string& name, const PreparedAsset& asset, int message_bits);

struct StreamSettings {
  // The quantisation step (largest side / 2^bits) must stay well below the mark's move in the
  // unit box (T a, 7e-4 or more at the default tolerance): 16 bits give 1.5e-5.
  int quant_bits = 16;
  std::map<std::string, std::string> metadata;  // codec rules; never secrets, never the payload
};

struct CopyFiles {
  std::vector<std::uint8_t> stream;  // .mmc of the watermarked polyhedron
  Mesh decoded;  // that stream decoded and subdivided at asset.levels (what a viewer shows)
};

// The decoded mesh is the decoded (quantised) stream refined at asset.levels: the surface
// `meshmark decompress` gives for the stream, with vertices numbered from the polyhedron's face
// order (the codec does not keep face order), so an unmodified copy corresponds to the asset's
// refined mesh index by index. triangles_only: triangulate (STL).
// Throws InputError("encode", ...) if the polyhedron cannot be encoded.
CopyFiles make_copy_files(const PreparedAsset& asset, const Mesh& marked_control,
                          const StreamSettings& stream, bool triangles_only);

// The mark's own cost on the surface a customer sees: how far the copy's decoded vertices lie
// from the same vertices of the unmarked polyhedron refined at asset.levels, over the diagonal
// of the unmarked decoded part. `max` bounds the Hausdorff distance between the two surfaces
// (vertex to corresponding vertex); quantisation of the stream is included.
struct MarkCost {
  double max = 0, rms = 0;
};
// `decoded` is CopyFiles::decoded (triangulated or not). Throws std::invalid_argument when its
// vertices do not correspond to the asset's refined vertices.
MarkCost mark_cost(const PreparedAsset& asset, const Mesh& decoded);

// The strength every copy of the part is given so that the mark moves no decoded vertex farther
// than `budget` (a fraction of the diagonal, as MarkCost::max): settings' strength scaled by the
// budget over the largest move of kReferenceMarks seeded marks at that strength, less a margin
// for the copies' own signs, and never above settings' strength. The move is linear in the
// strength and the same for every copy up to its key's signs, so one strength serves the part's
// copies (detection then computes a suspect's evidence once for them). Deterministic.
constexpr int kReferenceMarks = 4;
double strength_within(const PreparedAsset& asset, const WatermarkSettings& settings, double budget);

}  // namespace mm::jobs
