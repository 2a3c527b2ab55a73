// Offline commands working on files only, no store:
//   meshmark info MESH                      vertex and face counts
//   meshmark sample NAME OUT | --list       a generated CAD-like sample part
//   meshmark keygen OUT                     a random 256-bit customer key, mode 0600, never overwrites
//   meshmark attack noise|subdivide|similarity IN OUT ...   seeded attacks for demos and tests
// embed and extract live in mark_commands.cpp.
#include <sys/stat.h>

#include <algorithm>
#include <iostream>
#include <memory>
#include <sstream>

#include "cli/attacks.h"
#include "cli/commands.h"
#include "cli/file_util.h"
#include "cli/key_file.h"
#include "cli/mesh_files.h"
#include "meshio/read_mesh.h"
#include "samples/samples.h"
#include "subdivision/subdivide.h"

namespace mm::cli {
namespace {

std::string canonical_sample_name(std::string name) {
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

void add_sample_command(CLI::App& app) {
  struct Args {
    std::string name, out;
    bool list = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("sample", "Write a generated CAD-like sample part (closed, sharp-featured)");
  c->add_option("name", a->name, "part name (see --list); '-' and '_' are interchangeable");
  c->add_option("output", a->out, "mesh file to write (.off, .obj, .ply, .stl)");
  c->add_flag("--list", a->list, "list the parts with their vertex and face counts");
  c->callback([a] {
    const auto parts = samples::sample_parts();
    if (a->list) {
      for (const auto& p : parts)
        std::cout << p.name << "  " << p.mesh.num_vertices() << " vertices, " << p.mesh.num_faces() << " faces\n";
      return;
    }
    if (a->name.empty() || a->out.empty()) throw CLI::ValidationError("sample", "needs NAME and OUT (or --list)");
    const std::string name = canonical_sample_name(a->name);
    for (const auto& p : parts)
      if (p.name == name) {
        if (!is_mesh_path(a->out))
          throw InputError(a->out, "unknown output type (expected .stl, .obj, .off or .ply)");
        write_mesh(p.mesh, a->out);
        std::cout << a->out << ": " << p.name << ", " << p.mesh.num_vertices() << " vertices, "
                  << p.mesh.num_faces() << " faces\n";
        return;
      }
    std::string names;
    for (const auto& p : parts) names += (names.empty() ? "" : ", ") + p.name;
    throw CLI::ValidationError("sample", "unknown part '" + a->name + "' (known: " + names + ")");
  });
}

void add_keygen_command(CLI::App& app) {
  auto out = std::make_shared<std::string>();
  auto* c = app.add_subcommand("keygen",
                               "Write a new random 256-bit customer key (hex, mode 0600); never overwrites, never prints the key");
  c->add_option("output", *out, "key file to create")->required();
  c->callback([out] {
    const Key key = generate_key();
    if (!write_file_exclusive(*out, key_file_text(key), 0600))
      throw CommandFailed(1, *out + ": exists; keygen never overwrites a key (remove it first if you really mean to)");
    std::cout << *out << ": new 256-bit key, mode 0600, fingerprint " << key_fingerprint(key) << "\n";
  });
}

void add_attack_commands(CLI::App& app) {
  auto* attack = app.add_subcommand(
      "attack", "Seeded attacks on a mesh or .mmc stream, for demos and robustness tests (OUT by extension)");
  attack->require_subcommand(1);
  struct Args {
    std::string in, out;
    double amplitude = 0.001;
    std::uint64_t seed = 1;
    int levels = 1;
    bool linear = false;
    double scale = 1, rotate = 0;
    std::vector<double> shift{0, 0, 0};
  };
  auto a = std::make_shared<Args>();
  auto io = [a](CLI::App* c) {
    c->add_option("input", a->in, "mesh or .mmc stream (its control polyhedron) to attack")->required();
    c->add_option("output", a->out, "mesh or .mmc file to write")->required();
  };
  // Streams written by an attack keep the input stream's quantisation, or 16 bits for a mesh.
  auto finish = [a](const InputFile& in, const Mesh& m, const std::string& what) {
    write_output(m, a->out, in.stream ? in.quant_bits : 16, {});
    std::cout << a->out << ": " << what << ", " << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
  };

  auto* noise = attack->add_subcommand(
      "noise", "Add uniform noise in [-A, A] x (largest bounding-box side) to every coordinate");
  io(noise);
  noise->add_option("-A,--amplitude", a->amplitude, "A, relative to the largest bounding-box side")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0))->check(kFiniteNumber);
  noise->add_option("--seed", a->seed, "random seed (same seed, same file)")->capture_default_str();
  noise->callback([a, finish] {
    InputFile in = load_input(a->in);
    add_uniform_noise(in.mesh.points, a->amplitude, a->seed);
    std::ostringstream what;
    what << "uniform noise " << a->amplitude << " x largest side, seed " << a->seed;
    finish(in, in.mesh, what.str());
  });

  auto* sub = attack->add_subcommand(
      "subdivide", "Refine with Stam-Loop quad/triangle subdivision (creases of a .mmc input kept)");
  io(sub);
  sub->add_option("-L,--levels", a->levels, "subdivision steps")->capture_default_str()->check(CLI::Range(1, 5));
  sub->add_flag("--linear", a->linear,
                "split each face into four at its edges' midpoints instead: the same surface, four times the "
                "faces per step, no vertex moved");
  sub->callback([a, finish] {
    InputFile in = load_input(a->in);
    Mesh m;
    try {
      m = a->linear ? subdivide_linear(in.mesh, a->levels) : subdivide(in.mesh, a->levels);
    } catch (const InputError& e) {
      throw InputError(a->in, "cannot subdivide: " + e.reason());
    } catch (const std::invalid_argument& e) {
      throw InputError(a->in, std::string("cannot subdivide: ") + e.what());
    }
    finish(in, m, std::to_string(a->levels) + (a->linear ? " midpoint split(s)" : " subdivision level(s)"));
  });

  auto* sim = attack->add_subcommand(
      "similarity", "Scale, rotate about the z axis, then shift (in units of the largest bounding-box side)");
  io(sim);
  sim->add_option("--scale", a->scale, "uniform scale factor")->capture_default_str()->check(CLI::Range(1e-6, 1e6))->check(kFiniteNumber);
  sim->add_option("--rotate", a->rotate, "rotation about the z axis, degrees")->capture_default_str()->check(kFiniteNumber);
  sim->add_option("--shift", a->shift, "translation X Y Z, relative to the largest bounding-box side")
      ->expected(3)->capture_default_str()->check(kFiniteNumber);
  sim->callback([a, finish] {
    InputFile in = load_input(a->in);
    apply_similarity(in.mesh.points, a->scale, a->rotate, {a->shift[0], a->shift[1], a->shift[2]});
    finish(in, in.mesh, "similarity");
  });
}

}  // namespace

void add_offline_commands(CLI::App& app) {
  auto* info = app.add_subcommand("info", "Print vertex and face counts of a mesh");
  auto path = std::make_shared<std::string>();
  info->add_option("mesh", *path, "mesh file (STL, OBJ, OFF, PLY)")->required();
  info->callback([path] {
    auto m = read_mesh(*path);
    std::cout << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
  });
  add_sample_command(app);
  add_keygen_command(app);
  add_attack_commands(app);
  add_mark_commands(app);
}

}  // namespace mm::cli
