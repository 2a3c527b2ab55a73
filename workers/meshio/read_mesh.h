// Reading and writing meshes: STL (binary/ASCII, duplicate vertices welded), OBJ, OFF (ASCII/binary), PLY
// (ASCII and binary), 3MF through lib3mf, glTF 2.0 and GLB (also Draco-compressed) through
// tinygltf and libdraco. Hand-written strict parsers: OpenMesh's readers narrow coordinates to
// float and accept truncated or malformed files silently (see docs/mesh-io.md), which the
// watermark cannot afford. Every failure throws InputError naming the source and the reason.
//
// read_mesh returns the file faithfully: vertex order as in the file (STL: order of first
// appearance after welding), faces in file order with their vertex order, no face dropped for
// being non-manifold. The only faces removed are degenerate ones (fewer than 3 distinct
// vertices, which no polygon mesh can hold); they are counted in ReadReport, never silent.
// For a mesh that loads into a halfedge structure use read_mesh_manifold (repair_manifold.h).
#pragma once
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "meshio/mesh.h"

namespace mm {

struct ReadReport {
  std::string format;                // "stl-binary", "stl-ascii", "obj", "off", "off-binary", "ply-ascii", "ply-binary", "3mf", "glb", "gltf"
  std::string unit;                  // the file's length unit where it states one (3MF: "millimeter", ...; glTF: "meter"), else ""
  int objects = 1;                   // 3MF: build items read; glTF: triangle primitives read (all, concatenated)
  std::vector<std::string> object_names;  // 3MF: every build item's object name, in build order ("" unnamed)
  bool draco = false;                // glTF: a primitive was Draco-compressed (KHR_draco_mesh_compression)
  int welded_vertices = 0;           // STL corners merged into an earlier vertex with equal coordinates
  int collapsed_faces = 0;           // faces that listed a vertex twice in a row; the repeat was removed
  int degenerate_faces_dropped = 0;  // faces with < 3 distinct vertices (or a vertex repeated apart)
  int unreferenced_vertices = 0;     // kept (vertex order matters), but no face uses them
};

// A path's extension in lower case without the dot ("" when it has none): the format it names.
std::string lower_extension(const std::string& path);

// The formats read_mesh reads and write_mesh writes, as lower-case extensions without the dot.
const std::vector<std::string>& mesh_formats();
bool is_mesh_format(const std::string& extension);
// "stl, obj, off, ply, 3mf, glb or gltf", for messages.
std::string mesh_format_list();
// Whether the format stores triangles only (stl, 3mf, glb, gltf): its writer fans polygons.
bool stores_triangles_only(const std::string& extension);

// Reads by extension (.stl .obj .off .ply .3mf, case-insensitive). Throws InputError for missing,
// empty, truncated or malformed files, NaN/Inf coordinates, absurd counts, indices out of range,
// unknown formats, and files with no (non-degenerate) face.
struct ReadOptions {
  // 3MF: read only the build items whose object has this name (several items may share it); ""
  // reads the whole build. Another format with a name is an InputError: it holds no named objects.
  std::string object;
};
Mesh read_mesh(const std::string& path, ReadReport* report = nullptr, const ReadOptions& options = {});

// The same from bytes already in memory (an upload, a blob); format is one of mesh_formats();
// source names the data in error messages.
Mesh parse_mesh(std::string_view bytes, const std::string& format, const std::string& source,
                ReadReport* report = nullptr, const ReadOptions& options = {});

// A file's bytes with read_mesh's checks: InputError for a missing file, a folder, an empty file
// or one over 2 GiB.
std::string read_input_file(const std::string& path);

// Writes by extension: .stl (binary, float32 coordinates, polygons fan-triangulated), .obj, .off,
// .ply (ASCII, doubles in shortest round-trip form, so reading back gives identical positions),
// .3mf (float32 coordinates, polygons fan-triangulated, one object, in options.unit), .glb and
// .gltf (float32, fanned, one mesh; buffers embedded; Draco-compressed with options.draco_bits).
// Written to a temporary file in the same folder, fsynced, then renamed over path: a failure
// leaves nothing half-written. Creases and corners are not stored by these formats.
// Throws InputError(path, reason) for an invalid mesh or an I/O failure.
struct WriteOptions {
  std::string unit;    // 3MF: the length unit (ReadReport::unit's names); "" = millimeter
  int draco_bits = 0;  // GLB/glTF: 0 = plain float32; 8..30 = Draco-compressed, positions quantised to these bits
  std::string object;  // 3MF: the object's name ("" = unnamed)
};
void write_mesh(const Mesh& mesh, const std::string& path, const WriteOptions& options = {});
// The bytes write_mesh writes to `path` (format from its extension), without writing them:
// InputError for an unknown format or a mesh that cannot be written.
std::string mesh_file_bytes(const Mesh& mesh, const std::string& path, const WriteOptions& options = {});

// A 3MF package of several meshes, each its own object (named where the name is not empty) and
// build item, in order: a build of several parts. InputError for an unknown unit.
std::string three_mf_build_bytes(const std::vector<std::pair<std::string, Mesh>>& objects, const std::string& unit = "");

// A double as the text writers print it: the shortest text that reads back to the same value
// (std::to_chars). Cache keys and records name their parameters with it too.
std::string shortest_text(double d);

}  // namespace mm
