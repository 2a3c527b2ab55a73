#include "jobs/protect.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "codec/stream.h"
#include "jobs/payload.h"
#include "meshio/normalize.h"
#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"

namespace mm::jobs {

Mesh make_copy(const PreparedAsset& asset, const Key& key, const Nonce& nonce,
               std::uint64_t payload, const WatermarkSettings& settings) {
  Mesh copy = asset.control;
  copy.points = embed(asset.basis, asset.control.points, payload_to_bits(payload, settings.message_bits),
                      key, nonce, settings.params);
  undo(asset.normalization, copy.points);
  return copy;
}

CopyFiles make_copy_files(const PreparedAsset& asset, const Mesh& marked_control,
                          const StreamSettings& stream, bool triangles_only) {
  CopyFiles f;
  CodecParams cp;
  cp.quant_bits = stream.quant_bits;
  cp.metadata = stream.metadata;
  f.stream = encode(marked_control, cp);
  // The stream keeps the vertex order but not the face order; refining the decoded points with the
  // polyhedron's own faces gives the same surface with the asset's refined vertex numbering.
  Mesh quantised = marked_control;
  quantised.points = decode(f.stream, "copy stream").mesh.points;
  f.decoded = asset.levels > 0 ? decompress_to_level(quantised, asset.levels) : quantised;
  if (triangles_only) f.decoded = triangulate(f.decoded);
  return f;
}

MarkCost mark_cost(const PreparedAsset& asset, const Mesh& decoded) {
  Mesh unmarked = asset.control;
  undo(asset.normalization, unmarked.points);
  if (asset.levels > 0) unmarked = decompress_to_level(unmarked, asset.levels);
  if (unmarked.num_vertices() != decoded.num_vertices())
    throw std::invalid_argument("mark cost: the decoded copy has " + std::to_string(decoded.num_vertices()) +
                                " vertices, the asset's refined mesh " + std::to_string(unmarked.num_vertices()));
  const double diagonal = (unmarked.points.colwise().maxCoeff() - unmarked.points.colwise().minCoeff()).norm();
  const Eigen::VectorXd moved = (decoded.points - unmarked.points).rowwise().norm();
  MarkCost c;
  if (diagonal > 0 && moved.size() > 0) {
    c.max = moved.maxCoeff() / diagonal;
    c.rms = std::sqrt(moved.squaredNorm() / static_cast<double>(moved.size())) / diagonal;
  }
  return c;
}

double strength_within(const PreparedAsset& asset, const WatermarkSettings& settings, double budget) {
  // Room for a copy's own signs to move a vertex farther than the references did; a copy that
  // still passes the budget is given its own strength (the caller checks).
  constexpr double kMargin = 1.15;
  if (!(budget > 0)) throw std::invalid_argument("mark budget must be positive");
  const SubdivisionOperator op = build_subdivision(asset.control, asset.levels);
  const Points& refined = op.refined.points;
  const double diagonal = (refined.colwise().maxCoeff() - refined.colwise().minCoeff()).norm();
  double largest = 0;
  for (int r = 0; r < kReferenceMarks; ++r) {
    Key key{};
    Nonce nonce{};
    for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(0x5a ^ (r * 37 + i * 11));
    for (std::size_t i = 0; i < nonce.size(); ++i) nonce[i] = static_cast<std::uint8_t>(0xa5 ^ (r * 53 + i * 7));
    const std::uint64_t payload = 0x9e3779b97f4a7c15ULL * static_cast<std::uint64_t>(r + 1);
    const Points moved = embed(asset.basis, asset.control.points, payload_to_bits(payload, settings.message_bits),
                               key, nonce, settings.params) -
                         asset.control.points;
    largest = std::max(largest, apply_subdivision(op, moved).rowwise().norm().maxCoeff());
  }
  if (!(largest > 0) || !(diagonal > 0)) return settings.params.strength;
  return std::min(settings.params.strength, settings.params.strength * budget * diagonal / (kMargin * largest));
}

int coefficients_per_bit(const PreparedAsset& asset, int message_bits) {
  return 3 * asset.control.num_vertices() / message_bits;
}

std::string weak_spread_warning(const std::string& name, const PreparedAsset& asset, int message_bits) {
  const int spread = coefficients_per_bit(asset, message_bits);
  if (spread >= kWeakSpread) return "";
  return name + ": " + std::to_string(asset.control.num_vertices()) + " control vertices spread the " +
         std::to_string(message_bits) + "-bit payload over " + std::to_string(spread) +
         " coefficients a bit (fewer than " + std::to_string(kWeakSpread) +
         "): a copy may not be attributed even if leaked unmodified; fewer watermark.message_bits spread it wider";
}

}  // namespace mm::jobs
