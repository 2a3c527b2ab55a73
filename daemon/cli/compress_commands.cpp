// compress, decompress, compare: the compression half of the product, on files only.
//   meshmark compress IN OUT.mmc    fit a subdivision control polyhedron and encode it
//   meshmark decompress IN.mmc OUT  subdivide a stream to a level (or a triangle count), write a mesh
//   meshmark compare A B            symmetric Hausdorff / RMS / mean distance relative to A's diagonal
//   meshmark render IN OUT.png      a picture of a mesh, a decoded stream or its control polyhedron
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "cli/commands.h"
#include "codec/stream.h"
#include "fitting/compress.h"
#include "meshio/read_mesh.h"
#include "quality/coordinate_slack.h"
#include "quality/surface_distance.h"
#include "render/render_mesh.h"
#include "subdivision/decompress.h"

namespace mm::cli {
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  for (size_t i = 0; i < suffix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i])
      return false;
  return true;
}

// The subdivision level a stream was fitted at (stored in its metadata by `compress`).
int stream_levels(const DecodedStream& s, int fallback) {
  auto it = s.metadata.find("levels");
  if (it == s.metadata.end()) return fallback;
  try {
    int l = std::stoi(it->second);
    return l >= 0 && l <= 6 ? l : fallback;
  } catch (const std::exception&) {
    return fallback;
  }
}

// A mesh file as is, or a .mmc stream subdivided to `level` (its own fitted level when < 0).
Mesh load_surface(const std::string& path, int level) {
  if (!ends_with(path, ".mmc")) return read_mesh(path);
  auto s = decode_file(path);
  return decompress_to_level(s.mesh, level >= 0 ? level : stream_levels(s, 3));
}

// Fewest bits whose worst rounding error (half a grid step on each axis) stays below a fifth of
// the tolerance; the grid spans the control mesh's longest side.
int auto_bits(const Mesh& control, double tolerance) {
  Eigen::RowVector3d lo = control.points.colwise().minCoeff(), hi = control.points.colwise().maxCoeff();
  const double side = (hi - lo).maxCoeff(), diagonal = (hi - lo).norm();
  if (!(side > 0)) return 12;
  for (int bits = kMinQuantBits; bits < kMaxQuantBits; ++bits) {
    const double step = quantization_for(control.points, bits).step;  // the grid encode() uses
    if (0.5 * step * std::sqrt(3.0) <= 0.2 * tolerance * diagonal) return bits;
  }
  return kMaxQuantBits;
}

// Rate-distortion snapping (CodecParams::snap_cells) at one grid: spends the tolerance the
// decoded surface leaves unused on bytes. Allowances come from the plain stream's per-coordinate
// slack (quality/coordinate_slack.h) times a scale (kSnapScales): the slack is a first-order bound that
// assumes every neighbour moves the worst way at once, which the encoder's moves rarely do (at
// scale 2 the 8-bit grids of most bench parts barely move; at 4 about half of the streams meet
// the tolerance unrepaired). A candidate that misses the tolerance is repaired, not discarded:
// its moved coordinates whose slack on the snapped surface is (nearly) gone go back to their
// nearest values, the rest stay, so the encoder's other choices are kept (re-snapping with
// those coordinates frozen instead lets the greedy coder move others and missed again: abc8
// 0.598 -> 0.531 -> 0.535 -> 0.590 %). The repair's slack uses the dense measurement's own part
// samples (the default SamplingParams), so a violation the measurement saw is seen; with a
// quarter of them bracket-3's violation was missed. The decoded candidate is measured like the
// plain one (decoded_distance); returns the smallest that meets the tolerances and is smaller
// than `smaller_than`, or no bytes.
struct SnapCandidate {
  std::vector<std::uint8_t> bytes;
  SurfaceDistance distance;
};
// Scales tried, each at B and B + 1. Measured on the bench parts (bytes with 4 alone -> with 8
// alone -> with 2 alone): abc5 456 / 445 / 441, abc8 564 / 574 / 583, bracket-3 508 / 520 / 521,
// rocker 1283 / 1280 / 1353, blade 1660 / 1960 / 1755, abc9 171 / 170 / 172, abc6 207 / 211 /
// 219; no scale is best everywhere, 4 and 2 together take the best but for 1-3 bytes.
constexpr double kSnapScales[] = {4, 2};
constexpr int kSnapRepairs = 2;
constexpr std::uint8_t kMaxSnapCells = 8;

template <class Meets>
SnapCandidate snap_search(const Mesh& part, const Mesh& control, int levels, CodecParams params, double tolerance,
                          std::size_t smaller_than, const Meets& meets, const std::string& name) {
  // The slack is a guide (the measurement decides), so a quarter of the dense samples will do.
  SamplingParams guide;
  guide.samples = 50000;
  const DecodedStream plain = decode(encode(control, params), name);
  const double step = plain.quantization.step;
  const std::vector<double> slack = coordinate_slack(part, plain.mesh, levels, tolerance, guide);
  SnapCandidate best;
  for (double scale : kSnapScales) {
    CodecParams snapping = params;
    snapping.snap_cells.resize(slack.size());
    for (std::size_t i = 0; i < slack.size(); ++i)
      snapping.snap_cells[i] = static_cast<std::uint8_t>(
          std::clamp(std::floor(scale * slack[i] / step), 0.0, static_cast<double>(kMaxSnapCells)));
    std::vector<std::uint8_t> bytes = encode(control, snapping);
    for (int repair = 0; bytes.size() < smaller_than; ++repair) {
      DecodedStream snapped = decode(bytes, name);
      const SurfaceDistance d = decoded_distance(part, snapped.mesh, levels);
      if (meets(d)) {
        smaller_than = bytes.size();
        best = {std::move(bytes), d};
        break;
      }
      if (repair == kSnapRepairs) break;
      // The codec keeps the vertex order, so the plain and snapped grids line up row by row.
      // The second repair also takes back moves with under a quarter cell of slack left.
      const std::vector<double> left = coordinate_slack(part, snapped.mesh, levels, tolerance);
      int reverted = 0;
      for (std::size_t i = 0; i < left.size(); ++i) {
        const int v = static_cast<int>(i / 3), axis = static_cast<int>(i % 3);
        if (left[i] <= 0.25 * repair * step && snapped.grid(v, axis) != plain.grid(v, axis)) {
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

char fmt_buf[64];
const char* pct(double x) {
  std::snprintf(fmt_buf, sizeof fmt_buf, "%.4f%%", 100 * x);
  return fmt_buf;
}

}  // namespace

void add_compress_commands(CLI::App& app) {
  {
    struct Args {
      std::string in, out;
      CompressOptions o;
      int bits = 0;  // 0: chosen from the tolerance
      double rms_tolerance = 0;  // 0: the bit search checks the Hausdorff distance only
      bool json = false;
      bool snap = true;
    };
    auto a = std::make_shared<Args>();
    auto* c = app.add_subcommand(
        "compress", "Fit a sharp-featured subdivision control polyhedron to a mesh, write a .mmc stream");
    c->add_option("input", a->in, "mesh file (STL, OBJ, OFF, PLY)")->required();
    c->add_option("output", a->out, "stream file to write (.mmc)")->required();
    c->add_option("--tolerance", a->o.tolerance,
                  "target symmetric Hausdorff distance relative to the bounding box diagonal")
        ->capture_default_str()->check(CLI::Range(1e-6, 0.5));
    c->add_option("--max-vertices", a->o.max_vertices, "control vertex budget")
        ->capture_default_str()->check(CLI::Range(4, 10000000));
    c->add_option("--levels", a->o.levels, "subdivision levels the fit is measured at")
        ->capture_default_str()->check(CLI::Range(1, 5));
    c->add_option("--angle", a->o.angle_degrees, "dihedral angle (degrees) above which an edge is a crease")
        ->capture_default_str()->check(CLI::Range(1.0, 179.0));
    c->add_option("--bits", a->bits,
                  "quantisation bits per coordinate (default: the fewest, from 8 up, whose decoded "
                  "surface meets the tolerance; at most the bits whose rounding error stays below a "
                  "fifth of the tolerance)")
        ->check(CLI::Range(kMinQuantBits, kMaxQuantBits));
    c->add_option("--rms-tolerance", a->rms_tolerance,
                  "also bound the RMS distance (relative to the diagonal) when choosing the bits: "
                  "coarse grids add noise that the Hausdorff distance alone does not see")
        ->check(CLI::Range(1e-6, 0.5));
    c->add_flag("!--no-snap", a->snap,
                "keep every coordinate on its nearest grid value (no rate-distortion snapping)");
    c->add_flag("--json", a->json, "print the summary as JSON");
    c->callback([a] {
      Mesh mesh = read_mesh(a->in);
      auto t0 = std::chrono::steady_clock::now();
      // The quality code's dense measurement is the one reported below: let it decide when a
      // round meets the tolerance too.
      CompressOptions options = a->o;
      // Timed apart: the speed target is the fit's; the dense check costs the same per round
      // whatever the part's size (200,000 samples a side).
      double verify_seconds = 0;
      options.verify = [&mesh, &verify_seconds, levels = a->o.levels](const Mesh& control) {
        const auto v0 = std::chrono::steady_clock::now();
        const double h = decoded_distance(mesh, control, levels).hausdorff_relative();
        verify_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - v0).count();
        return h;
      };
      CompressResult r = compress(mesh, options, a->in);
      double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      CodecParams params;
      params.metadata["levels"] = std::to_string(r.levels);
      std::vector<std::uint8_t> bytes;
      SurfaceDistance d;
      const Mesh* chosen = &r.control;
      const auto meets = [&a](const SurfaceDistance& m) {
        return m.hausdorff_relative() <= a->o.tolerance &&
               (a->rms_tolerance <= 0 || m.rms_relative() <= a->rms_tolerance);
      };
      const auto t1 = std::chrono::steady_clock::now();
      // Each polyhedron that met the tolerance (fewest vertices first; just the best one when
      // the fit missed it): its bits are the fewest whose decoded surface (quantised,
      // subdivided, measured by the quality code) still meets the tolerance, from 8 up to the
      // conservative rounding bound (the bound alone when --bits is given or the fit missed);
      // the smallest stream wins. A stream no smaller than the best so
      // far ends a polyhedron's search unmeasured: more bits only add bytes.
      std::vector<const Mesh*> polyhedra;
      for (const auto& fitted : r.candidates) polyhedra.push_back(&fitted.control);
      if (polyhedra.empty()) polyhedra.push_back(&r.control);
      bool best_meets = false;
      for (const Mesh* control : polyhedra) {
        const int bound = a->bits > 0 ? a->bits : auto_bits(*control, a->o.tolerance);
        const int lowest = a->bits > 0 || !r.tolerance_met ? bound : kMinQuantBits;
        for (int b = lowest; b <= bound; ++b) {
          CodecParams p = params;
          p.quant_bits = b;
          auto candidate = encode(*control, p);
          if (best_meets && candidate.size() >= bytes.size()) break;
          SurfaceDistance m = decoded_distance(mesh, decode(candidate, a->out).mesh, r.levels);
          // Nothing met yet: keep the last tried, so that something is written (as before).
          if (meets(m) || (!best_meets && b == bound && bytes.empty())) {
            bytes = std::move(candidate);
            d = m;
            params.quant_bits = b;
            chosen = control;
            best_meets = meets(m);
            if (best_meets) break;
          }
        }
      }
      // Rate-distortion snapping (snap_search above) on the chosen polyhedron, at its bits and
      // one more: each snapped stream is decoded and measured like the plain ones, and the
      // smallest that meets the tolerances wins (the plain one included).
      const std::size_t unsnapped_bytes = bytes.size();
      bool snapped_stream = false;
      if (a->snap && a->bits == 0 && meets(d)) {
        const int top = std::min(params.quant_bits + 1, auto_bits(*chosen, a->o.tolerance));
        const double tolerance = a->o.tolerance * d.diagonal;
        for (int bits = params.quant_bits; bits <= top; ++bits) {
          CodecParams at = params;
          at.quant_bits = bits;
          SnapCandidate s = snap_search(mesh, *chosen, r.levels, at, tolerance, bytes.size(), meets, a->out);
          if (s.bytes.empty()) continue;
          bytes = std::move(s.bytes);
          d = s.distance;
          params.quant_bits = bits;
          snapped_stream = true;
        }
      }
      const double select_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
      write_stream_file(a->out, bytes);
      nlohmann::json j{{"input", a->in},
                       {"output", a->out},
                       {"input_vertices", mesh.num_vertices()},
                       {"input_faces", mesh.num_faces()},
                       {"control_vertices", chosen->num_vertices()},
                       {"control_faces", chosen->num_faces()},
                       {"creases", chosen->creases.size()},
                       {"corners", chosen->corners.size()},
                       {"candidates", polyhedra.size()},
                       {"levels", r.levels},
                       {"bits", params.quant_bits},
                       {"stream_bytes", bytes.size()},
                       {"hausdorff", d.hausdorff_relative()},
                       {"rms", d.rms_relative()},
                       {"mean", d.mean_relative()},
                       {"tolerance", a->o.tolerance},
                       {"tolerance_met", d.hausdorff_relative() <= a->o.tolerance},
                       {"rms_tolerance", a->rms_tolerance > 0 ? nlohmann::json(a->rms_tolerance) : nlohmann::json()},
                       {"rms_tolerance_met", a->rms_tolerance <= 0 || d.rms_relative() <= a->rms_tolerance},
                       {"rounds", r.rounds},
                       {"seconds", seconds},
                       {"verify_seconds", verify_seconds},
                       {"bits_seconds", select_seconds},
                       {"snapped", snapped_stream},
                       {"unsnapped_bytes", unsnapped_bytes}};
      if (a->json) {
        std::cout << j.dump(2) << "\n";
        return;
      }
      std::cout << a->out << ": " << bytes.size() << " bytes, " << chosen->num_vertices()
                << " control vertices, " << chosen->num_faces() << " faces, "
                << chosen->creases.size() << " creases, " << chosen->corners.size()
                << " corners (from " << mesh.num_vertices() << " vertices)\n";
      std::cout << "level " << r.levels << " vs input: Hausdorff " << pct(d.hausdorff_relative());
      std::cout << ", RMS " << pct(d.rms_relative());
      std::cout << ", mean " << pct(d.mean_relative()) << " of the diagonal";
      std::cout << (d.hausdorff_relative() <= a->o.tolerance ? "" : " (tolerance not reached within the budget)")
                << (a->rms_tolerance <= 0 || d.rms_relative() <= a->rms_tolerance ? "" : " (RMS tolerance not reached)")
                << "; " << seconds << " s\n";
    });
  }
  {
    struct Args {
      std::string in, out;
      int level = -1;
      long long faces = 0;
    };
    auto a = std::make_shared<Args>();
    auto* c = app.add_subcommand("decompress", "Subdivide a .mmc stream and write the surface as a mesh");
    c->add_option("input", a->in, "stream file (.mmc)")->required();
    c->add_option("output", a->out, "mesh file to write (STL, OBJ, OFF, PLY)")->required();
    auto* lvl = c->add_option("--level", a->level, "subdivision level (default: the level it was fitted at)")
                    ->check(CLI::Range(0, 6));
    c->add_option("--faces", a->faces, "smallest level with at least this many triangles (at most level 6)")
        ->check(CLI::Range(1LL, 1LL << 40))
        ->excludes(lvl);
    c->callback([a] {
      auto s = decode_file(a->in);
      Mesh m = a->faces > 0 ? decompress_to_triangle_count(s.mesh, a->faces)
                            : decompress_to_level(s.mesh, a->level >= 0 ? a->level : stream_levels(s, 3));
      if (ends_with(a->out, ".stl")) m = triangulate(m);
      write_mesh(m, a->out);
      std::cout << a->out << ": " << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
    });
  }
  {
    struct Args {
      std::string a, b;
      int level = -1;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    auto* c = app.add_subcommand(
        "compare", "Symmetric Hausdorff, RMS and mean surface distance between two meshes, "
                   "relative to the first one's bounding box diagonal (.mmc streams are subdivided)");
    c->add_option("a", a->a, "reference mesh or stream")->required();
    c->add_option("b", a->b, "other mesh or stream")->required();
    c->add_option("--level", a->level, "level for .mmc inputs (default: the level they were fitted at)")
        ->check(CLI::Range(0, 6));
    c->add_flag("--json", a->json, "print JSON");
    c->callback([a] {
      Mesh ma = load_surface(a->a, a->level), mb = load_surface(a->b, a->level);
      auto d = surface_distance(ma, mb);
      if (a->json) {
        nlohmann::json j{{"a", a->a},
                         {"b", a->b},
                         {"diagonal", d.diagonal},
                         {"hausdorff", d.hausdorff_relative()},
                         {"rms", d.rms_relative()},
                         {"mean", d.mean_relative()},
                         {"hausdorff_abs", d.hausdorff},
                         {"rms_abs", d.rms},
                         {"mean_abs", d.mean},
                         {"a_to_b", {{"max", d.a_to_b.max / d.diagonal}, {"rms", d.a_to_b.rms / d.diagonal},
                                     {"samples", d.a_to_b.samples}}},
                         {"b_to_a", {{"max", d.b_to_a.max / d.diagonal}, {"rms", d.b_to_a.rms / d.diagonal},
                                     {"samples", d.b_to_a.samples}}}};
        std::cout << j.dump(2) << "\n";
        return;
      }
      std::cout << "Hausdorff " << pct(d.hausdorff_relative());
      std::cout << ", RMS " << pct(d.rms_relative());
      std::cout << ", mean " << pct(d.mean_relative()) << " of the diagonal (" << d.diagonal << ")\n";
    });
  }
  {
    struct Args {
      std::string in, out;
      bool control = false, wire = false;
      int level = -1, width = 800, height = 600;
      double azimuth = 35, elevation = 25;
    };
    auto a = std::make_shared<Args>();
    auto* c = app.add_subcommand("render", "Write a PNG picture of a mesh or .mmc stream (creases in red)");
    c->add_option("input", a->in, "mesh file or .mmc stream")->required();
    c->add_option("output", a->out, "PNG file to write")->required();
    c->add_flag("--control", a->control, "draw a stream's control polyhedron (with its edges) instead of its surface");
    c->add_flag("--wire", a->wire, "draw every polygon edge");
    c->add_option("--level", a->level, "level for .mmc surfaces (default: the fitted level)")->check(CLI::Range(0, 6));
    c->add_option("--azimuth", a->azimuth, "view direction around the up axis, degrees")->capture_default_str();
    c->add_option("--elevation", a->elevation, "view direction above the horizon, degrees")->capture_default_str();
    c->add_option("--width", a->width)->capture_default_str()->check(CLI::Range(16, 8192));
    c->add_option("--height", a->height)->capture_default_str()->check(CLI::Range(16, 8192));
    c->callback([a] {
      Mesh m;
      if (ends_with(a->in, ".mmc") && a->control) {
        m = decode_file(a->in).mesh;
      } else {
        m = load_surface(a->in, a->level);
        m.creases.clear();  // a subdivided surface carries many crease edges; draw the shape only
      }
      Camera cam;
      cam.azimuth_deg = a->azimuth;
      cam.elevation_deg = a->elevation;
      RenderOptions o;
      o.width = a->width;
      o.height = a->height;
      o.draw_wire = a->wire || a->control;
      o.draw_corners = a->control;
      render_mesh(m, cam, o).write_png(a->out);
      std::cout << a->out << "\n";
    });
  }
}

}  // namespace mm::cli
