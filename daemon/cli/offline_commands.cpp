// Offline commands working on files only, no store: info (later keygen, embed, extract).
#include <iostream>

#include "cli/commands.h"
#include "meshio/read_mesh.h"

namespace mm::cli {

void add_offline_commands(CLI::App& app) {
  auto* info = app.add_subcommand("info", "Print vertex and face counts of a mesh");
  auto path = std::make_shared<std::string>();
  info->add_option("mesh", *path, "mesh file (STL, OBJ, OFF, PLY)")->required();
  info->callback([path] {
    auto m = read_mesh(*path);
    std::cout << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
  });
}

}  // namespace mm::cli
