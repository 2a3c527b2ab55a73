// Loading and writing the files the offline commands take: a mesh (STL, OBJ, OFF, PLY, 3MF,
// glTF, GLB), a CAD part (STEP, IGES: tessellated) or a .mmc stream, chosen by extension. The bytes are read once, so the hash recorded is the hash of what
// was parsed.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "meshio/mesh.h"

namespace mm::cli {

bool is_stream_path(const std::string& path);  // ends in .mmc (any case)
bool is_mesh_path(const std::string& path);    // ends in one of mesh_formats() (any case)
bool is_part_path(const std::string& path);    // ends in one of part_formats(): a mesh or a CAD part
bool is_triangle_path(const std::string& path);  // a mesh format that stores triangles only

struct InputFile {
  Mesh mesh;          // the mesh, or the stream's decoded control polyhedron (creases, corners)
  bool stream = false;
  int quant_bits = 0;  // stream only
  std::map<std::string, std::string> metadata;  // stream only
  std::string sha256;  // of the file's bytes
};

// Throws InputError(path, reason) for a missing, unreadable, malformed file or an unknown extension.
InputFile load_input(const std::string& path);

// Writes a mesh by extension (write_mesh), or a .mmc stream at `quant_bits` with `metadata`.
// Atomic either way. Throws InputError(path, reason).
void write_output(const Mesh& mesh, const std::string& path, int quant_bits = 16,
                  const std::map<std::string, std::string>& metadata = {});

}  // namespace mm::cli
