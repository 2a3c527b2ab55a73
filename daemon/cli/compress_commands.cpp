// compress, decompress, compare: the compression half of the product, on files only.
//   meshmark compress IN OUT.mmc    fit a subdivision control polyhedron and encode it
//   meshmark decompress IN.mmc OUT  subdivide a stream to a level (or a triangle count), write a mesh
//   meshmark compare A B            symmetric Hausdorff / RMS / mean distance relative to A's diagonal
//   meshmark render IN OUT.png      a picture of a mesh, a decoded stream or its control polyhedron
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <ctime>
#include <sys/resource.h>
#include <mutex>

#include "cad/read_part.h"
#include "cli/commands.h"
#include "cli/mesh_files.h"
#include "codec/stream.h"
#include "fitting/compress.h"
#include "meshio/read_mesh.h"
#include "compression/compress_part.h"
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
  if (!ends_with(path, ".mmc")) return read_part(path);
  auto s = decode_file(path);
  return decompress_to_level(s.mesh, level >= 0 ? level : stream_levels(s, 3));
}

// This process's peak resident set so far (getrusage: kilobytes on Linux), in MB.
double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

// ParallelFor on threads of this process: the angles' fits run at once.
void run_on_threads(int n, int at_once, const std::function<void(int)>& task) {
  std::atomic<int> next{0};
  const auto work = [&] {
    for (int k; (k = next++) < n;) task(k);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < at_once; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

// A JSON number, or null where it was not measured.
nlohmann::json number_if(bool measured, double x) { return measured ? nlohmann::json(x) : nlohmann::json(); }

char fmt_buf[64];
const char* pct(double x) {
  std::snprintf(fmt_buf, sizeof fmt_buf, "%.4f%%", 100 * x);
  return fmt_buf;
}

// Why the written stream misses the tolerance, with a hint when the user chose the angles.
std::string missed_tolerance(const CompressResult& r, const CompressOptions& o, bool angles_given) {
  return " (tolerance not reached " + tolerance_miss_reason(r, o) +
         (!stopped_at_budget(r, o) && angles_given ? "; a fold flatter than the crease angle? a smaller --angle may help)"
                                                   : ")");
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
      bool fast = false;  // a protect job's compression: one angle, no coarsening, no stream search
      bool best_effort = false;  // write the closest stream when the tolerance is not met
      // 45 and 55 besides the usual 35: a part with many edges between them (blade) fits with
      // fewer vertices when they are smooth. Parts whose crease network is the same at several
      // of them are fitted once per network.
      std::vector<double> angles{35.0, 45.0, 55.0};
      // Tried in turn when none of the default angles meets the tolerance. Not after an
      // explicit --angle: the user chose which edges are creases.
      std::vector<double> fallback_angles = fallback_crease_angles();
      int threads = 0;  // 0: one per core
    };
    auto a = std::make_shared<Args>();
    a->o.coarsen = true;  // the command's job is the smallest stream; protect jobs keep the fast path
    auto* c = app.add_subcommand(
        "compress", "Fit a sharp-featured subdivision control polyhedron to a mesh, write a .mmc stream");
    c->add_option("input", a->in, "mesh file (STL, OBJ, OFF, PLY, 3MF, glTF, GLB)")->required();
    c->add_option("output", a->out, "stream file to write (.mmc)")->required();
    c->add_option("--tolerance", a->o.tolerance,
                  "target symmetric Hausdorff distance relative to the bounding box diagonal")
        ->capture_default_str()->check(CLI::Range(1e-6, 0.5))->check(kFiniteNumber);
    c->add_option("--max-vertices", a->o.max_vertices, "control vertex budget")
        ->capture_default_str()->check(CLI::Range(4, 10000000));
    c->add_option("--levels", a->o.levels, "subdivision levels the fit is measured at")
        ->capture_default_str()->check(CLI::Range(1, 5));
    auto* angle_option = c->add_option("--angle", a->angles,
                  "dihedral angle (degrees) above which an edge is a crease; several (comma-separated): "
                  "each distinct crease network is fitted and the smallest stream kept (one angle is "
                  "up to 3x faster). By default, when none of 35, 45, 55 meets the tolerance, 30, 25 "
                  "and 20 are tried in turn until one does")
        ->delimiter(',')->capture_default_str()->check(CLI::Range(1.0, 179.0))->check(kFiniteNumber);
    c->add_option("--bits", a->bits,
                  "quantisation bits per coordinate (default: the fewest, from 6 up, whose decoded "
                  "surface meets the tolerance; at most the bits whose rounding error stays below a "
                  "fifth of the tolerance, more only for a polyhedron that meets it by a hair)")
        ->check(CLI::Range(kMinQuantBits, kMaxQuantBits));
    c->add_option("--rms-tolerance", a->rms_tolerance,
                  "also bound the RMS distance (relative to the diagonal) when choosing the bits: "
                  "coarse grids add noise that the Hausdorff distance alone does not see")
        ->check(CLI::Range(1e-6, 0.5))->check(kFiniteNumber);
    c->add_flag("!--no-snap", a->snap,
                "keep every coordinate on its nearest grid value (no rate-distortion snapping, no "
                "grid descent)");
    c->add_option("--seed", a->o.seed,
                  "sampling seed of the fit (each seed is deterministic; the vertex count that meets "
                  "the tolerance varies with it)")
        ->capture_default_str();
    c->add_flag("!--no-quads", a->o.rail_quads,
                "fit triangles only (no quads on strips between two creases; faster, often larger)");
    c->add_flag("!--no-coarsen", a->o.coarsen,
                "keep the refinement rounds' polyhedron (no removal of control vertices after them; "
                "a 3-5x faster fit, streams about 9 % larger)");
    c->add_flag("--fast", a->fast,
                "compress as a protect job does, in under half the time: one crease angle (35 unless "
                "--angle), no coarsening, no stream search (the fewest bits from 6 up whose stream passes "
                "the check, nearest grid values, no snapping or renumbering); the stream is checked within "
                "the tolerance on the dense measurement's samples but not measured (no Hausdorff/RMS "
                "numbers: meshmark compare gives them); streams about a quarter larger");
    c->add_option("--threads", a->threads,
                  "fit the angles' crease networks on up to this many threads at once (default: one per "
                  "core; the stream is the same for any number)")
        ->check(CLI::Range(1, 256));
    c->add_flag("--best-effort", a->best_effort,
                "when the tolerance cannot be met within --max-vertices, write the closest stream and exit 0 "
                "(default: exit 1 and write nothing)");
    c->add_flag("--json", a->json, "print the summary as JSON");
    c->callback([a, angle_option] {
      Mesh mesh = read_part(a->in);
      auto t0 = std::chrono::steady_clock::now();
      // The quality code's dense measurement is the one reported below: let it decide when a
      // round meets the tolerance too.
      CompressOptions options = a->o;
      std::vector<double> angles = a->angles;
      if (a->fast) {
        options.coarsen = false;
        if (angle_option->count() == 0) angles = {angles.front()};
      }
      // Timed apart: the speed target is the fit's; the dense check costs the same per round
      // whatever the part's size (200,000 samples a side). CPU time of the calling thread: the
      // fits of several angles run at once.
      double verify_seconds = 0;
      std::mutex verify_mutex;
      // The part's samples and tree, built by the first measurement and shared by the fits'
      // threads and the bit search.
      const MeasuredSurface measured(mesh);
      options.verify = [&measured, &verify_seconds, &verify_mutex, levels = a->o.levels,
                        tolerance = a->o.tolerance](const Mesh& control) {
        const double v0 = thread_cpu_seconds();
        const bool meets = decoded_within(measured, control, levels, tolerance);
        const std::lock_guard<std::mutex> lock(verify_mutex);
        verify_seconds += thread_cpu_seconds() - v0;
        return meets;
      };
      PartOptions po;
      po.fit = options;
      po.angles = angles;
      po.fallback_angles = angle_option->count() > 0 ? std::vector<double>{} : a->fallback_angles;
      po.at_once = a->threads > 0 ? a->threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
      po.parallel = run_on_threads;
      po.stream.rms_tolerance = a->rms_tolerance;
      po.stream.bits = a->bits;
      po.stream.snap = a->snap;
      po.stream.quick = a->fast;
      po.stream.metadata["levels"] = std::to_string(a->o.levels);
      const CompressedPart part = compress_part(mesh, measured, po, a->in);
      const PartFits& fits = part.fits;
      const double select_seconds = part.stream_seconds;
      const double fit_wall_seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() - select_seconds;
      const double seconds = fits.cpu_seconds;
      const ChosenStream& s = part.stream;
      const Mesh* chosen = part.control;
      const FitAtAngle& chosen_fit = *part.fit;
      const CompressResult& r = chosen_fit.result;
      std::vector<double> fitted;
      nlohmann::json coarsened_angle;  // null: nothing coarsened
      for (const auto& f : fits.fits) {
        fitted.push_back(f.angle);
        if (f.coarsened) coarsened_angle = f.angle;
      }
      const std::vector<std::uint8_t>& bytes = s.bytes;
      const SurfaceDistance& d = s.distance;
      // Unmeasured (--fast), the stream was checked: it met both tolerances.
      const bool hausdorff_met = s.measured ? d.hausdorff_relative() <= a->o.tolerance : s.meets;
      const bool rms_met = a->rms_tolerance <= 0 || (s.measured ? d.rms_relative() <= a->rms_tolerance : s.meets);
      if (!(hausdorff_met && rms_met) && !a->best_effort) {
        std::string what = "the closest stream";
        if (s.measured) {
          what = "Hausdorff " + std::string(pct(d.hausdorff_relative()));
          what += ", RMS " + std::string(pct(d.rms_relative())) + " of the diagonal";
        }
        throw InputError(a->in, what +
                                    (hausdorff_met ? "" : missed_tolerance(r, options, angle_option->count() > 0)) +
                                    (rms_met ? "" : " (RMS tolerance not reached)") +
                                    "; no stream written (raise --max-vertices or --tolerance, or write the "
                                    "closest stream with --best-effort)");
      }
      write_stream_file(a->out, bytes);
      nlohmann::json j{{"input", a->in},
                       {"output", a->out},
                       {"input_vertices", mesh.num_vertices()},
                       {"input_faces", mesh.num_faces()},
                       {"control_vertices", chosen->num_vertices()},
                       {"control_faces", chosen->num_faces()},
                       {"quads", std::count_if(chosen->faces.begin(), chosen->faces.end(),
                                               [](const std::vector<int>& f) { return f.size() == 4; })},
                       {"creases", chosen->creases.size()},
                       {"corners", chosen->corners.size()},
                       {"candidates", part.candidates},
                       {"levels", r.levels},
                       {"bits", s.bits},
                       {"stream_bytes", bytes.size()},
                       {"hausdorff", number_if(s.measured, d.hausdorff_relative())},
                       {"rms", number_if(s.measured, d.rms_relative())},
                       {"mean", number_if(s.measured, d.mean_relative())},
                       {"measured", s.measured},
                       {"tolerance", a->o.tolerance},
                       {"tolerance_met", hausdorff_met},
                       {"rms_tolerance", a->rms_tolerance > 0 ? nlohmann::json(a->rms_tolerance) : nlohmann::json()},
                       {"rms_tolerance_met", rms_met},
                       {"fast", a->fast},
                       {"rounds", r.rounds},
                       {"round_vertices", r.round_vertices},
                       {"round_errors", r.round_errors},
                       {"round_warm", r.round_warm},
                       {"round_levels", r.round_levels},
                       {"angle", chosen_fit.angle},
                       {"angles_fitted", fitted},
                       {"angles_refused", fits.refused},
                       {"coarsen", options.coarsen},
                       {"coarsened_angle", coarsened_angle},
                       {"seed", a->o.seed},
                       {"seconds", seconds},
                       {"verify_seconds", verify_seconds},
                       {"fit_wall_seconds", fit_wall_seconds},
                       {"peak_rss_mb", peak_rss_mb()},
                       {"fit_threads", fits.threads},
                       {"bits_seconds", select_seconds},
                       {"snapped", s.snapped},
                       {"descended", s.descended},
                       {"unsnapped_bytes", s.unsnapped_bytes}};
      if (a->json) {
        std::cout << j.dump(2) << "\n";
        return;
      }
      std::cout << a->out << ": " << bytes.size() << " bytes, " << chosen->num_vertices()
                << " control vertices, " << chosen->num_faces() << " faces, "
                << chosen->creases.size() << " creases, " << chosen->corners.size()
                << " corners at crease angle " << chosen_fit.angle << " (from " << mesh.num_vertices()
                << " vertices)\n";
      if (s.measured) {
        std::cout << "level " << r.levels << " vs input: Hausdorff " << pct(d.hausdorff_relative());
        std::cout << ", RMS " << pct(d.rms_relative());
        std::cout << ", mean " << pct(d.mean_relative()) << " of the diagonal";
      } else {
        std::cout << "level " << r.levels << " vs input: Hausdorff within " << pct(a->o.tolerance)
                  << " of the diagonal by the dense check (not measured with --fast: meshmark compare "
                  << a->in << " " << a->out << " gives the numbers)";
      }
      std::cout << (hausdorff_met ? "" : missed_tolerance(r, options, angle_option->count() > 0))
                << (rms_met ? "" : " (RMS tolerance not reached)")
                << "; fit " << fit_wall_seconds << " s, bits " << select_seconds << " s\n";
    });
  }
  {
    struct Args {
      std::string in, out;
      int level = -1;
      long long faces = 0;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    auto* c = app.add_subcommand("decompress", "Subdivide a .mmc stream and write the surface as a mesh");
    c->add_option("input", a->in, "stream file (.mmc)")->required();
    c->add_option("output", a->out, "mesh file to write (STL, OBJ, OFF, PLY, 3MF, glTF, GLB)")->required();
    auto* lvl = c->add_option("--level", a->level, "subdivision level (default: the level it was fitted at)")
                    ->check(CLI::Range(0, 6));
    c->add_option("--faces", a->faces, "smallest level with at least this many triangles (at most level 6)")
        ->check(CLI::Range(1LL, 1LL << 40))
        ->excludes(lvl);
    c->add_flag("--json", a->json, "print the summary as JSON, with the decoding and subdivision times");
    c->callback([a] {
      const auto t0 = std::chrono::steady_clock::now();
      auto s = decode_file(a->in);
      const auto t1 = std::chrono::steady_clock::now();
      const int level = a->faces > 0 ? -1 : (a->level >= 0 ? a->level : stream_levels(s, 3));
      Mesh m = a->faces > 0 ? decompress_to_triangle_count(s.mesh, a->faces) : decompress_to_level(s.mesh, level);
      const auto t2 = std::chrono::steady_clock::now();
      if (is_triangle_path(a->out)) m = triangulate(m);
      write_mesh(m, a->out);
      if (a->json) {
        // Decoding includes reading the file; neither includes writing the mesh.
        const nlohmann::json j{{"input", a->in},
                               {"output", a->out},
                               {"level", level >= 0 ? nlohmann::json(level) : nlohmann::json()},
                               {"control_vertices", s.mesh.num_vertices()},
                               {"vertices", m.num_vertices()},
                               {"faces", m.num_faces()},
                               {"decode_seconds", std::chrono::duration<double>(t1 - t0).count()},
                               {"subdivide_seconds", std::chrono::duration<double>(t2 - t1).count()}};
        std::cout << j.dump(2) << "\n";
        return;
      }
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
    c->add_option("--azimuth", a->azimuth, "view direction around the up axis, degrees")->capture_default_str()->check(kFiniteNumber);
    c->add_option("--elevation", a->elevation, "view direction above the horizon, degrees")->capture_default_str()->check(kFiniteNumber);
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
