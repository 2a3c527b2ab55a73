// meshmark attack KIND IN OUT ...: the seeded attacks of workers/attacks on a mesh or a .mmc
// stream's control polyhedron, for demos, robustness tests and the detection benchmark. OUT by
// extension; a stream keeps the input stream's quantisation (16 bits for a mesh).
#include <iostream>
#include <memory>
#include <sstream>

#include "attacks/crop.h"
#include "attacks/perturb.h"
#include "attacks/retessellate.h"
#include "cli/commands.h"
#include "cli/mesh_files.h"
#include "subdivision/subdivide.h"

namespace mm::cli {
namespace {

struct Args {
  std::string in, out;
  std::vector<std::string> files;  // average: inputs, then the output
  double amplitude = 0.001;
  std::uint64_t seed = 1;
  int levels = 1;
  bool linear = false;
  double scale = 1, rotate = 0;
  std::vector<double> shift{0, 0, 0};
  int bits = 8;
  int iterations = 5;
  double lambda = 0.5;
  double keep = 0.5;
  bool from_high = false;
  double edge = 0.01;
  int remesh_iterations = 3;
  double alpha = 0.005, offset = 0;
};

// Library argument errors (std::invalid_argument) and CGAL's refusals become the input's errors.
template <typename F>
Mesh attacked(const std::string& path, F&& attack) {
  try {
    return attack();
  } catch (const InputError& e) {
    throw InputError(path, e.reason());
  } catch (const std::exception& e) {
    throw InputError(path, e.what());
  }
}

}  // namespace

void add_attack_commands(CLI::App& app) {
  auto* attack = app.add_subcommand(
      "attack", "Seeded attacks on a mesh or .mmc stream, for demos and robustness tests (OUT by extension)");
  attack->require_subcommand(1);
  auto a = std::make_shared<Args>();
  auto io = [a](CLI::App* c) {
    c->add_option("input", a->in, "mesh or .mmc stream (its control polyhedron) to attack")->required();
    c->add_option("output", a->out, "mesh or .mmc file to write")->required();
  };
  auto finish = [a](const InputFile& in, const Mesh& m, const std::string& what) {
    write_output(m, a->out, in.stream ? in.quant_bits : 16, {});
    std::cout << a->out << ": " << what << ", " << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
  };
  // An attack over the input mesh: load, attack, write.
  auto command = [a, attack, io, finish](const char* name, const char* help, auto&& body) {
    auto* c = attack->add_subcommand(name, help);
    io(c);
    c->callback([a, finish, body] {
      InputFile in = load_input(a->in);
      std::string what;
      Mesh m = attacked(a->in, [&] { return body(in.mesh, what); });
      finish(in, m, what);
    });
    return c;
  };
  auto text = [](auto... parts) {
    std::ostringstream s;
    (s << ... << parts);
    return s.str();
  };

  auto* noise = command("noise", "Add uniform noise in [-A, A] x (largest bounding-box side) to every coordinate",
                        [a, text](Mesh m, std::string& what) {
                          attacks::add_uniform_noise(m.points, a->amplitude, a->seed);
                          what = text("uniform noise ", a->amplitude, " x largest side, seed ", a->seed);
                          return m;
                        });
  noise->add_option("-A,--amplitude", a->amplitude, "A, relative to the largest bounding-box side")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0))->check(kFiniteNumber);
  noise->add_option("--seed", a->seed, "random seed (same seed, same file)")->capture_default_str();

  auto* sub = command("subdivide", "Refine with Stam-Loop quad/triangle subdivision (creases of a .mmc input kept)",
                      [a](Mesh m, std::string& what) {
                        what = std::to_string(a->levels) + (a->linear ? " midpoint split(s)" : " subdivision level(s)");
                        return a->linear ? subdivide_linear(std::move(m), a->levels) : subdivide(m, a->levels);
                      });
  sub->add_option("-L,--levels", a->levels, "subdivision steps")->capture_default_str()->check(CLI::Range(1, 5));
  sub->add_flag("--linear", a->linear,
                "split each face into four at its edges' midpoints instead: the same surface, four times the "
                "faces per step, no vertex moved");

  auto* sim = command("similarity", "Scale, rotate about the z axis, then shift (in units of the largest bounding-box side)",
                      [a](Mesh m, std::string& what) {
                        attacks::apply_similarity(m.points, a->scale, a->rotate, {a->shift[0], a->shift[1], a->shift[2]});
                        what = "similarity";
                        return m;
                      });
  sim->add_option("--scale", a->scale, "uniform scale factor")->capture_default_str()->check(CLI::Range(1e-6, 1e6))->check(kFiniteNumber);
  sim->add_option("--rotate", a->rotate, "rotation about the z axis, degrees")->capture_default_str()->check(kFiniteNumber);
  sim->add_option("--shift", a->shift, "translation X Y Z, relative to the largest bounding-box side")
      ->expected(3)->capture_default_str()->check(kFiniteNumber);

  auto* quant = command("quantize", "Round every coordinate to a grid of 2^bits cells along the largest side",
                        [a, text](Mesh m, std::string& what) {
                          attacks::quantize_coordinates(m.points, a->bits);
                          what = text("quantised to ", a->bits, " bits");
                          return m;
                        });
  quant->add_option("-b,--bits", a->bits, "bits per coordinate")->capture_default_str()->check(CLI::Range(1, 30));

  auto* smooth = command("smooth", "Laplacian (umbrella) smoothing: each vertex moves lambda of the way to its neighbours' mean",
                         [a, text](Mesh m, std::string& what) {
                           attacks::smooth_laplacian(m, a->iterations, a->lambda);
                           what = text("smoothed ", a->iterations, " times at lambda ", a->lambda);
                           return m;
                         });
  smooth->add_option("-n,--iterations", a->iterations, "smoothing steps")->capture_default_str()->check(CLI::Range(0, 10000));
  smooth->add_option("--lambda", a->lambda, "step size in (0, 1]")->capture_default_str()->check(CLI::Range(1e-9, 1.0))->check(kFiniteNumber);

  auto* reorder = command("reorder", "Renumber vertices and reorder faces at random (the same surface in another file order)",
                          [a, text](Mesh m, std::string& what) {
                            attacks::shuffle_order(m, a->seed);
                            what = text("reordered, seed ", a->seed);
                            return m;
                          });
  reorder->add_option("--seed", a->seed, "random seed")->capture_default_str();

  auto* crop = command("crop", "Keep the faces within the first KEEP of the bounding box along its longest axis",
                       [a, text](Mesh m, std::string& what) {
                         what = text("cropped to ", a->keep, " of the longest side", a->from_high ? " (high end)" : "");
                         return attacks::crop_along_longest_axis(m, a->keep, a->from_high);
                       });
  crop->add_option("-k,--keep", a->keep, "fraction of the longest side kept, in (0, 1]")->capture_default_str()->check(CLI::Range(1e-9, 1.0))->check(kFiniteNumber);
  crop->add_flag("--from-high", a->from_high, "keep the high end of the axis instead of the low end");

  auto* remesh = command("remesh", "Isotropic remeshing (CGAL) to edges of EDGE x the bounding-box diagonal, sharp edges kept",
                         [a, text](Mesh m, std::string& what) {
                           what = text("remeshed at ", a->edge, " x diagonal");
                           return attacks::remesh_isotropic(m, a->edge, a->remesh_iterations);
                         });
  remesh->add_option("-e,--edge", a->edge, "target edge length, relative to the diagonal")->capture_default_str()->check(CLI::Range(1e-4, 1.0))->check(kFiniteNumber);
  remesh->add_option("-n,--iterations", a->remesh_iterations, "remeshing rounds")->capture_default_str()->check(CLI::Range(1, 100));

  auto* simplify = command("simplify", "Edge-collapse simplification (CGAL, Lindstrom-Turk) keeping KEEP of the edges",
                           [a, text](Mesh m, std::string& what) {
                             what = text("simplified to ", a->keep, " of the edges");
                             return attacks::simplify_edges(m, a->keep);
                           });
  simplify->add_option("-k,--keep", a->keep, "fraction of the edges kept, in (0, 1]")->capture_default_str()->check(CLI::Range(1e-9, 1.0))->check(kFiniteNumber);

  auto* wrap = command("wrap", "Re-extract a watertight surface around the part (CGAL alpha wrapping), as a voxel remesh does",
                       [a, text](Mesh m, std::string& what) {
                         const double offset = a->offset > 0 ? a->offset : a->alpha / 30;
                         what = text("alpha-wrapped at alpha ", a->alpha, ", offset ", offset, " x diagonal");
                         return attacks::alpha_wrap(m, a->alpha, offset);
                       });
  wrap->add_option("--alpha", a->alpha, "alpha, relative to the diagonal")->capture_default_str()->check(CLI::Range(1e-4, 1.0))->check(kFiniteNumber);
  wrap->add_option("--offset", a->offset, "offset, relative to the diagonal (default alpha / 30)")->check(CLI::Range(0.0, 1.0))->check(kFiniteNumber);

  auto* average = attack->add_subcommand("average", "The vertex-wise mean of several copies with the same connectivity (collusion)");
  average->add_option("files", a->files, "two or more copies, then the file to write")->expected(3, 64)->required();
  average->callback([a] {
    const std::string out = a->files.back();
    std::vector<Mesh> copies;
    std::vector<std::string> names(a->files.begin(), a->files.end() - 1);
    bool stream = false;
    int bits = 16;
    for (const auto& name : names) {
      InputFile in = load_input(name);
      if (in.stream) stream = true, bits = in.quant_bits;
      copies.push_back(std::move(in.mesh));
    }
    const Mesh m = attacks::average_copies(copies, names);
    write_output(m, out, stream ? bits : 16, {});
    std::cout << out << ": the mean of " << copies.size() << " copies, " << m.num_vertices() << " vertices, "
              << m.num_faces() << " faces\n";
  });
}

}  // namespace mm::cli
