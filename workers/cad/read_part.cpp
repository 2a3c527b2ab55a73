#include "cad/read_part.h"

#include <algorithm>

namespace mm {

const std::vector<std::string>& part_formats() {
  static const std::vector<std::string> formats = [] {
    std::vector<std::string> f = mesh_formats();
    for (const char* cad : {"step", "stp", "iges", "igs"}) f.emplace_back(cad);
    return f;
  }();
  return formats;
}

bool is_part_format(const std::string& extension) {
  const auto& f = part_formats();
  return std::find(f.begin(), f.end(), extension) != f.end();
}

std::string part_format_list() {
  const auto& f = part_formats();
  std::string s;
  for (std::size_t i = 0; i < f.size(); ++i) s += (i == 0 ? "" : i + 1 == f.size() ? " or " : ", ") + f[i];
  return s;
}

Mesh parse_part(std::string_view bytes, const std::string& format, const std::string& source,
                const TessellationOptions& options, PartReport* report, const ReadOptions& read) {
  PartReport local;
  PartReport& out = report ? *report : local;
  out = PartReport{};
  if (!is_cad_format(format)) return parse_mesh(bytes, format, source, &out.read, read);
  if (!read.object.empty())
    throw InputError(source, "a " + format + " file holds no named objects (asked for \"" + read.object + "\")");
  Tessellation t;
  Mesh mesh = tessellate_cad(bytes, format, source, options, &t);
  out.read.format = t.format;
  out.read.unit = "millimeter";  // OpenCASCADE's readers convert lengths to millimetres
  out.read.objects = std::max(1, t.solids);
  out.read.degenerate_faces_dropped = t.degenerate_triangles_dropped;
  out.tessellation = t;
  return mesh;
}

Mesh read_part(const std::string& path, const TessellationOptions& options, PartReport* report,
               const ReadOptions& read) {
  const std::string format = lower_extension(path);
  if (!is_cad_format(format)) {
    PartReport local;
    PartReport& out = report ? *report : local;
    out = PartReport{};
    return read_mesh(path, &out.read, read);
  }
  return parse_part(read_input_file(path), format, path, options, report, read);
}

}  // namespace mm
