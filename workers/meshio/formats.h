// The per-format parsers behind read_mesh (internal to meshio). Each returns vertices and raw
// face index lists exactly as stored; indices are already checked against the vertex count.
// Shared clean-up (degenerate faces, zero faces) happens in read_mesh.cpp.
#pragma once
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "meshio/read_mesh.h"

namespace mm::formats {

Mesh parse_stl(std::string_view bytes, const std::string& source, ReadReport& report);
Mesh parse_obj(std::string_view bytes, const std::string& source, ReadReport& report);
Mesh parse_off(std::string_view bytes, const std::string& source, ReadReport& report);
Mesh parse_ply(std::string_view bytes, const std::string& source, ReadReport& report);
// object: only the build items whose object has this name ("" = every build item).
Mesh parse_3mf(std::string_view bytes, const std::string& source, ReadReport& report, const std::string& object = "");

// glTF 2.0 JSON (binary false; buffers embedded as data: URIs) or GLB (binary true).
Mesh parse_gltf(std::string_view bytes, const std::string& source, ReadReport& report, bool binary);
// One mesh, one node, float32 positions, uint32 indices of fanned triangles; with draco_bits
// (8..30) the primitive is Draco-compressed (KHR_draco_mesh_compression) at that quantisation.
std::string gltf_bytes(const Mesh& mesh, const std::string& path, bool binary, int draco_bits = 0);

// A 3MF package holding the mesh as one object in `unit` ("" = millimeter); path names it in errors.
std::string three_mf_bytes(const Mesh& mesh, const std::string& unit, const std::string& path,
                           const std::string& object_name = "");
// Several meshes, each its own object (named, when the name is not empty) and build item, in order.
std::string three_mf_bytes(const std::vector<std::pair<std::string, Mesh>>& objects, const std::string& unit,
                           const std::string& path);

// Throws InputError unless all three are finite; what names the item ("vertex 12").
void check_finite(const double* xyz, const std::string& source, const std::string& what);

}  // namespace mm::formats
