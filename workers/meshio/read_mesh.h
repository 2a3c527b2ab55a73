// Reading and writing meshes: STL (binary/ASCII, duplicate vertices welded), OBJ, OFF, PLY.
// Every failure throws InputError naming the file and the reason; faces are never dropped.
#pragma once
#include <string>

#include "meshio/mesh.h"

namespace mm {

// Reads by extension. Throws InputError for missing, empty, truncated, malformed files,
// NaN/Inf coordinates, absurd counts and unknown formats.
Mesh read_mesh(const std::string& path);

// Writes by extension (.stl binary, .obj, .off, .ply); written to a temporary file in the same
// folder and renamed, so a failed write leaves nothing half-written. Throws InputError.
void write_mesh(const Mesh& mesh, const std::string& path);

}  // namespace mm
