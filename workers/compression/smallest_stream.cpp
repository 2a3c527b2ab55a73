#include "compression/smallest_stream.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>

#include "codec/stream.h"
#include "compression/coordinate_slack.h"
#include "compression/grid_descent.h"

namespace mm {
namespace {

// Rate-distortion snapping (CodecParams::snap_cells) at one grid: spends the tolerance the
// decoded surface leaves unused on bytes. Allowances come from the plain stream's per-coordinate
// slack (compression/coordinate_slack.h) times a scale (kSnapScales): the slack is a first-order bound that
// assumes every neighbour moves the worst way at once, which the encoder's moves rarely do (at
// scale 2 the 8-bit grids of most bench parts barely move; at 4 about half of the streams meet
// the tolerance unrepaired). A candidate that misses the tolerance is repaired, not discarded:
// its moved coordinates whose slack on the snapped surface is (nearly) gone go back to their
// nearest values, the rest stay, so the encoder's other choices are kept (re-snapping with
// those coordinates frozen instead lets the greedy coder move others and missed again: abc8
// 0.598 -> 0.531 -> 0.535 -> 0.590 %). The repair's slack uses the dense measurement's own part
// samples (MeasuredSurface::samples), so a violation the measurement saw is seen; with a
// quarter of them bracket-3's violation was missed. The decoded candidate is checked like the
// plain one (`met`); returns the smallest that meets the tolerances and is smaller than
// `smaller_than`, or no bytes.
// Scales tried, each at B and B + 1. Measured on the bench parts (bytes with 4 alone -> with 8
// alone -> with 2 alone): abc5 456 / 445 / 441, abc8 564 / 574 / 583, bracket-3 508 / 520 / 521,
// rocker 1283 / 1280 / 1353, blade 1660 / 1960 / 1755, abc9 171 / 170 / 172, abc6 207 / 211 /
// 219; no scale is best everywhere, 4 and 2 together take the best but for 1-3 bytes.
constexpr double kSnapScales[] = {4, 2};
constexpr int kSnapRepairs = 2;
constexpr std::uint8_t kMaxSnapCells = 8;
// How far over the tolerance a polyhedron may be at its conservative bits to be tried on finer
// grids (quantisation error shrinks with the bits; a polyhedron far off does not come back).
constexpr double kCloseToTolerance = 1.1;
// How far over the tolerance a polyhedron's nearest grid values may be for its grid descent to be
// tried: the descent lowered the distance by 5-10 % where it helped (abc9 at 7 bits, 0.533 ->
// 0.495 %; abc6, 56 vertices at 9 bits, 0.571 -> 0.514 %), so from further off it is a measurement
// spent for nothing.
constexpr double kDescentReach = 1.15;
// A measurement beyond the descent's reach stops there (smallest_stream's main loop).
static_assert(kCloseToTolerance <= kDescentReach);
// Start vertices tried for the chosen polyhedron's numbering (evenly spaced in its numbering).
constexpr int kStarts = 64;

std::vector<std::uint8_t> snap_search(const MeasuredSurface& part, const Mesh& control, int levels, CodecParams params,
                                      double tolerance, std::size_t smaller_than,
                                      const std::function<bool(const Mesh&)>& met, const std::string& name) {
  // The slack is a guide (the measurement decides), so a quarter of the dense samples will do.
  SamplingParams guide;
  guide.samples = 50000;
  const DecodedStream plain = decode(encode(control, params), name);
  const double step = plain.quantization.step;
  const std::vector<double> slack = coordinate_slack(part, plain.mesh, levels, tolerance, guide);
  std::vector<std::uint8_t> best;
  for (double scale : kSnapScales) {
    CodecParams snapping = params;
    snapping.snap_cells.resize(slack.size());
    for (std::size_t i = 0; i < slack.size(); ++i)
      snapping.snap_cells[i] = static_cast<std::uint8_t>(
          std::clamp(std::floor(scale * slack[i] / step), 0.0, static_cast<double>(kMaxSnapCells)));
    std::vector<std::uint8_t> bytes = encode(control, snapping);
    for (int repair = 0; bytes.size() < smaller_than; ++repair) {
      DecodedStream snapped = decode(bytes, name);
      if (met(snapped.mesh)) {
        smaller_than = bytes.size();
        best = std::move(bytes);
        break;
      }
      if (repair == kSnapRepairs) break;
      // The codec keeps the vertex order, so the plain and snapped grids line up row by row.
      // The second repair also takes back moves with under a quarter cell of slack left.
      const double reverted_up_to = 0.25 * repair * step;
      const std::vector<double> left =
          coordinate_slack(part, snapped.mesh, levels, tolerance, part.params(), reverted_up_to);
      int reverted = 0;
      for (std::size_t i = 0; i < left.size(); ++i) {
        const int v = static_cast<int>(i / 3), axis = static_cast<int>(i % 3);
        if (left[i] <= reverted_up_to && snapped.grid(v, axis) != plain.grid(v, axis)) {
          snapped.grid(v, axis) = plain.grid(v, axis);
          ++reverted;
        }
      }
      if (reverted == 0) break;
      // Extreme values never move, so the repaired positions keep the grid; encoded without
      // snapping they are coded exactly.
      snapped.mesh.points = dequantize(snapped.grid, snapped.quantization);
      bytes = encode(snapped.mesh, params);
    }
  }
  return best;
}

// The stream's grid values numbered from other start vertices (in_traversal_order): the
// traversal, and with it the ranks and predictions, follow the start, and over 64 starts the
// smallest stream is 1-3 % below the first (blade 1177 -> 1156 bytes, abc6 207 -> 203). The
// surface is the same, but the samples a measurement takes of it follow its numbering, so the
// caller checks a smaller stream again. Returns no bytes when no start codes smaller.
std::vector<std::uint8_t> cheapest_numbering(const std::vector<std::uint8_t>& stream, int bits, CodecParams params,
                                             const std::string& name) {
  const DecodedStream written = decode(stream, name);
  params.quant_bits = bits;
  const int n = written.mesh.num_vertices(), starts = std::min(n, kStarts);
  std::vector<std::uint8_t> best;
  for (int k = 1; k < starts; ++k) {
    auto bytes = encode(in_traversal_order(written.mesh, static_cast<int>(static_cast<long long>(k) * n / starts)), params);
    if (bytes.size() < (best.empty() ? stream.size() : best.size())) best = std::move(bytes);
  }
  return best;
}

// StreamSearch::quick: `control` at the fewest bits, from 6 up to its conservative bits, whose
// nearest grid values meet the tolerances (the search's first step, without grid descent), in
// its own numbering; past the conservative bits, every other bit, only after a fit that met the
// tolerance and while the stream stays within kCloseToTolerance of it (the search's rule for a
// polyhedron within the tolerance by a hair). Checked, not measured, unless an RMS bound needs
// the numbers or nothing meets the tolerances. A check that fails is cheap (it stops at the
// first sample beyond the tolerance): over the nine bench parts, going up from 6 bits rather
// than starting at the conservative bits costs 0-130 ms and saves 10-30 % of the bytes.
template <class Within, class MeasuredIfMet>
ChosenStream quick_stream(const MeasuredSurface& part, const Mesh& control, const StreamSearch& search,
                          const CodecParams& params, const Within& within, const MeasuredIfMet& measured_if_met,
                          const std::string& name) {
  const int bound = search.bits > 0 ? search.bits : conservative_bits(control, search.tolerance);
  const int lowest = search.bits > 0 || !search.fit_met ? bound : kMinQuantBits;
  ChosenStream out;
  for (int b = lowest; b <= kMaxQuantBits; b += b < bound ? 1 : 2) {
    CodecParams p = params;
    p.quant_bits = b;
    std::vector<std::uint8_t> bytes = encode(control, p);
    const Mesh decoded = decode(bytes, name).mesh;
    std::optional<SurfaceDistance> whole;
    const bool ok = search.rms_tolerance > 0 ? (whole = measured_if_met(decoded)).has_value() : within(decoded, 1.0);
    if (ok || b == bound) {  // the bound's stream is written when no grid meets the tolerances
      out.bytes = std::move(bytes);
      out.bits = b;
      out.meets = ok;
      out.measured = whole.has_value();
      if (whole) out.distance = *whole;
    }
    if (ok) break;
    if (b >= bound && (search.bits > 0 || !search.fit_met || !within(decoded, kCloseToTolerance))) break;
  }
  out.unsnapped_bytes = out.bytes.size();
  if (!out.meets) {
    out.distance = decoded_distance(part, decode(out.bytes, name).mesh, search.levels);
    out.measured = true;
  }
  return out;
}

}  // namespace

int conservative_bits(const Mesh& control, double tolerance) {
  Eigen::RowVector3d lo = control.points.colwise().minCoeff(), hi = control.points.colwise().maxCoeff();
  const double side = (hi - lo).maxCoeff(), diagonal = (hi - lo).norm();
  if (!(side > 0)) return 12;
  for (int bits = kMinQuantBits; bits < kMaxQuantBits; ++bits) {
    const double step = quantization_for(control.points, bits).step;  // the grid encode() uses
    if (0.5 * step * std::sqrt(3.0) <= 0.2 * tolerance * diagonal) return bits;
  }
  return kMaxQuantBits;
}

ChosenStream smallest_stream(const Mesh& part, const std::vector<const Mesh*>& polyhedra, const StreamSearch& search,
                             const std::string& name) {
  return smallest_stream(MeasuredSurface(part), polyhedra, search, name);
}

ChosenStream smallest_stream(const MeasuredSurface& measured_part, const std::vector<const Mesh*>& polyhedra,
                             const StreamSearch& search, const std::string& name) {
  if (polyhedra.empty()) throw std::invalid_argument("smallest_stream: no polyhedron");
  const std::function<bool(const SurfaceDistance&)> meets = [&search](const SurfaceDistance& m) {
    return m.hausdorff_relative() <= search.tolerance &&
           (search.rms_tolerance <= 0 || m.rms_relative() <= search.rms_tolerance);
  };
  // Whether the decoded surface's Hausdorff distance is within `factor` times the tolerance: the
  // answer without the numbers (decoded_within), which is all the search needs of a candidate.
  // Only the stream written is measured whole (below).
  const auto within = [&measured_part, &search](const Mesh& decoded, double factor) {
    return decoded_within(measured_part, decoded, search.levels, factor * search.tolerance);
  };
  // The whole measurement (stopped early beyond the Hausdorff tolerance) when the stream meets
  // the tolerances, else nothing: for a stream that is written if it meets them, whose numbers
  // are then not measured again.
  const auto measured_if_met = [&](const Mesh& decoded) {
    auto d = decoded_distance_within(measured_part, decoded, search.levels, search.tolerance);
    if (d && !meets(*d)) d.reset();
    return d;
  };
  // Whether it meets the tolerances: an RMS bound needs every sample's distance, so then the
  // whole measurement decides.
  const std::function<bool(const Mesh&)> met = [&](const Mesh& decoded) {
    return search.rms_tolerance <= 0 ? within(decoded, 1.0) : measured_if_met(decoded).has_value();
  };
  CodecParams params;
  params.metadata = search.metadata;
  if (search.quick) return quick_stream(measured_part, *polyhedra.front(), search, params, within, measured_if_met, name);
  ChosenStream out;
  bool measured = false;  // out.distance is the written stream's
  // The chosen polyhedron's points: its own, or descended on the grid (grid_descent.h).
  std::optional<Mesh> descended;
  // Keeps a stream that a check found within the tolerances (`checked_within`; not so for the search's
  // fallback, kept though it missed), or, with `whole`, one measured whole (which then says
  // whether it meets them).
  const auto keep = [&](std::vector<std::uint8_t>&& bytes, int bits, std::size_t k, std::optional<Mesh>&& on_grid,
                        const std::optional<SurfaceDistance>& whole = std::nullopt, bool checked_within = true) {
    out.bytes = std::move(bytes);
    out.bits = bits;
    out.polyhedron = static_cast<int>(k);
    out.descended = on_grid.has_value();
    descended = std::move(on_grid);
    out.meets = whole ? meets(*whole) : checked_within;
    measured = whole.has_value();
    if (whole) out.distance = *whole;
  };
  // Per polyhedron, whether it came within kCloseToTolerance of the tolerance at its
  // conservative bits (where checked).
  std::vector<char> close_at_bound(polyhedra.size(), 0);
  // The fewest bits per polyhedron, the smallest stream over them. A stream no smaller than the
  // best so far ends a polyhedron's search unchecked: more bits only add bytes.
  for (std::size_t k = 0; k < polyhedra.size(); ++k) {
    const Mesh& control = *polyhedra[k];
    const int bound = search.bits > 0 ? search.bits : conservative_bits(control, search.tolerance);
    const int lowest = search.bits > 0 || !search.fit_met ? bound : kMinQuantBits;
    for (int b = lowest; b <= bound; ++b) {
      CodecParams p = params;
      p.quant_bits = b;
      auto candidate = encode(control, p);
      if (out.meets && candidate.size() >= out.bytes.size()) break;
      const Mesh decoded = decode(candidate, name).mesh;
      // Nothing met yet and this is the first polyhedron's last try: it is written if nothing
      // meets the tolerances later. When it is its only try (fixed bits, or a fit that missed)
      // it is likely the stream written, so it is measured whole now; in the search it is
      // checked like the others and measured at the end only if it is written (fandisk's first
      // polyhedron missed at its bound: a whole measurement, 0.24 s, for nothing).
      const bool fallback = !out.meets && b == bound && out.bytes.empty();
      if (fallback && lowest == bound) {
        const SurfaceDistance m = decoded_distance(measured_part, decoded, search.levels);
        keep(std::move(candidate), b, k, std::nullopt, m);
        close_at_bound[k] = m.hausdorff_relative() <= kCloseToTolerance * search.tolerance;
        if (out.meets) break;
        if (!(m.hausdorff_relative() <= kDescentReach * search.tolerance)) continue;
      } else {
        if (met(decoded)) {
          keep(std::move(candidate), b, k, std::nullopt);
          break;
        }
        if (fallback) keep(std::move(candidate), b, k, std::nullopt, std::nullopt, false);
        // Beyond the descent's reach (and kCloseToTolerance below it) a miss is all the search
        // needs to know.
        if (!within(decoded, kDescentReach)) continue;
        if (b == bound) close_at_bound[k] = within(decoded, kCloseToTolerance);
      }
      // Missed at these bits by little: the grid values chosen for the surface may still meet
      // them.
      if (search.snap && search.bits == 0 && search.fit_met) {
        Mesh on_grid = descended_on_grid(control, b, search.levels);
        auto bytes = encode(on_grid, p);
        if (out.meets && bytes.size() >= out.bytes.size()) break;
        if (met(decode(bytes, name).mesh)) {
          keep(std::move(bytes), b, k, std::move(on_grid));
          break;
        }
      }
    }
  }
  // A polyhedron the fit measured within the tolerance can miss it at the conservative bits when
  // it met it by a hair (abc6 at seed 3: 0.515 % at 10 bits, 0.498 % at 16): rather than write a
  // stream off the tolerance, finer grids for those that came close, every other bit up to the
  // format's limit. Nothing met above, so every polyhedron was checked at its bound there.
  if (!out.meets && search.bits == 0 && search.fit_met) {
    for (std::size_t k = 0; k < polyhedra.size() && !out.meets; ++k) {
      if (!close_at_bound[k]) continue;
      const Mesh& control = *polyhedra[k];
      CodecParams p = params;
      for (int b = conservative_bits(control, search.tolerance) + 2; b <= kMaxQuantBits && !out.meets; b += 2) {
        p.quant_bits = b;
        auto candidate = encode(control, p);
        if (met(decode(candidate, name).mesh)) {
          keep(std::move(candidate), b, k, std::nullopt);
        }
      }
    }
  }
  // The cheapest numbering of the chosen stream; then snapping on the chosen polyhedron, at its
  // bits and one more: each snapped stream is decoded and checked like the plain ones, and the
  // smallest that meets the tolerances wins (the plain one included), numbered cheapest too.
  // A smaller numbering is checked; the `last` one, which nothing can replace, is measured whole
  // instead (the same answer, and the numbers reported).
  const auto renumber = [&](bool last) {
    std::vector<std::uint8_t> c = cheapest_numbering(out.bytes, out.bits, params, name);
    if (c.empty()) return;
    const Mesh decoded = decode(c, name).mesh;
    std::optional<SurfaceDistance> whole;
    if (last) {
      whole = measured_if_met(decoded);
      if (!whole) return;
    } else if (!met(decoded)) {
      return;
    }
    out.bytes = std::move(c);
    measured = whole.has_value();
    if (whole) out.distance = *whole;
  };
  const bool snapping = search.snap && search.bits == 0 && out.meets;
  if (search.bits == 0 && out.meets) renumber(!snapping);
  out.unsnapped_bytes = out.bytes.size();
  if (snapping) {
    const Mesh& control = descended ? *descended : *polyhedra[static_cast<std::size_t>(out.polyhedron)];
    const int top = std::min(out.bits + 1, conservative_bits(control, search.tolerance));
    const double tolerance = search.tolerance * measured_part.diagonal();
    for (int bits = out.bits; bits <= top; ++bits) {
      CodecParams at = params;
      at.quant_bits = bits;
      std::vector<std::uint8_t> s = snap_search(measured_part, control, search.levels, at, tolerance, out.bytes.size(), met, name);
      if (s.empty()) continue;
      out.bytes = std::move(s);
      out.bits = bits;
      out.snapped = true;
      measured = false;  // out.distance, if any, is the plain stream's
    }
    if (out.snapped) renumber(true);
  }
  // The numbers reported are the written stream's, measured as `meshmark compare` measures it.
  if (!measured) out.distance = decoded_distance(measured_part, decode(out.bytes, name).mesh, search.levels);
  return out;
}

}  // namespace mm
