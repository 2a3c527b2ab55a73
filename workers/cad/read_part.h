// A part as the service takes it: a mesh file (meshio/read_mesh.h) or a CAD file tessellated
// (cad/tessellate.h), chosen by format. The one list of input formats for the daemon and CLI.
#pragma once
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cad/tessellate.h"
#include "meshio/read_mesh.h"

namespace mm {

// Every format parse_part reads: mesh_formats(), then step, stp, iges, igs.
const std::vector<std::string>& part_formats();
bool is_part_format(const std::string& extension);
// "stl, obj, ..., gltf, step, stp, iges or igs", for messages.
std::string part_format_list();

struct PartReport {
  ReadReport read;                          // format, unit ("millimeter" for CAD parts), counts
  std::optional<Tessellation> tessellation; // CAD parts: how the mesh was made
};

// The part in `bytes` as a mesh (format: one of part_formats()); read.object picks a 3MF part's
// named objects. InputError(source, reason).
Mesh parse_part(std::string_view bytes, const std::string& format, const std::string& source,
                const TessellationOptions& options = {}, PartReport* report = nullptr, const ReadOptions& read = {});
// The same from a file, its format from its extension.
Mesh read_part(const std::string& path, const TessellationOptions& options = {}, PartReport* report = nullptr,
               const ReadOptions& read = {});

}  // namespace mm
