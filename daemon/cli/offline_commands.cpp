// Offline commands working on files only, no store:
//   meshmark info MESH                      vertex and face counts
//   meshmark sample NAME OUT | --list       a generated CAD-like sample part
//   meshmark keygen OUT                     a random 256-bit customer key, mode 0600, never overwrites
// attack lives in attack_commands.cpp, embed and extract in mark_commands.cpp.
#include <sys/stat.h>

#include <algorithm>
#include <iostream>
#include <memory>
#include <sstream>

#include "cli/commands.h"
#include "cli/file_util.h"
#include "cli/key_file.h"
#include "cli/mesh_files.h"
#include "meshio/read_mesh.h"
#include "samples/samples.h"

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
