#include "meshio/read_mesh.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

#include "meshio/formats.h"

namespace mm {
namespace {

// Larger inputs are not CAD parts we can process; refusing early keeps memory bounded.
constexpr std::uintmax_t kMaxFileBytes = std::uintmax_t(2) << 30;


// Removes a vertex listed twice in a row (cyclically); drops faces that still do not have at
// least 3 distinct vertices. Counted in the report: never silent.
void clean_faces(Mesh& mesh, ReadReport& report) {
  std::vector<std::vector<int>> kept;
  kept.reserve(mesh.faces.size());
  for (auto& f : mesh.faces) {
    std::vector<int> g;
    g.reserve(f.size());
    for (int v : f)
      if (g.empty() || g.back() != v) g.push_back(v);
    while (g.size() > 1 && g.front() == g.back()) g.pop_back();
    if (g.size() != f.size()) ++report.collapsed_faces;
    std::vector<int> sorted = g;
    std::sort(sorted.begin(), sorted.end());
    bool repeated = std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
    if (g.size() < 3 || repeated) {
      ++report.degenerate_faces_dropped;
      if (g.size() != f.size()) --report.collapsed_faces;  // counted once, as dropped
      continue;
    }
    kept.push_back(std::move(g));
  }
  mesh.faces = std::move(kept);
  std::vector<char> used(static_cast<size_t>(mesh.num_vertices()), 0);
  for (const auto& f : mesh.faces)
    for (int v : f) used[static_cast<size_t>(v)] = 1;
  report.unreferenced_vertices = static_cast<int>(std::count(used.begin(), used.end(), 0));
}

}  // namespace

std::string read_input_file(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  auto st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw InputError(path, "no such file");
  if (fs::is_directory(st)) throw InputError(path, "is a directory, not a mesh file");
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw InputError(path, "cannot determine file size: " + ec.message());
  if (size == 0) throw InputError(path, "empty file");
  if (size > kMaxFileBytes)
    throw InputError(path, "file too large (" + std::to_string(size) + " bytes, limit 2 GiB)");
  std::string bytes(static_cast<size_t>(size), '\0');
  size_t got = std::fread(bytes.data(), 1, bytes.size(), f.get());
  if (got != bytes.size()) throw InputError(path, "read error after " + std::to_string(got) + " bytes");
  return bytes;
}

namespace formats {
void check_finite(const double* xyz, const std::string& source, const std::string& what) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(xyz[k]))
      throw InputError(source, std::string("non-finite coordinate (") +
                                   (std::isnan(xyz[k]) ? "NaN" : "Inf") + ") in " + what);
}
}  // namespace formats

const std::vector<std::string>& mesh_formats() {
  static const std::vector<std::string> formats{"stl", "obj", "off", "ply", "3mf", "glb", "gltf"};
  return formats;
}

bool is_mesh_format(const std::string& extension) {
  const auto& f = mesh_formats();
  return std::find(f.begin(), f.end(), extension) != f.end();
}

bool stores_triangles_only(const std::string& extension) {
  return extension == "stl" || extension == "3mf" || extension == "glb" || extension == "gltf";
}

std::string mesh_format_list() {
  const auto& f = mesh_formats();
  std::string s;
  for (std::size_t i = 0; i < f.size(); ++i) s += (i == 0 ? "" : i + 1 == f.size() ? " or " : ", ") + f[i];
  return s;
}

Mesh parse_mesh(std::string_view bytes, const std::string& format, const std::string& source,
                ReadReport* report, const ReadOptions& options) {
  ReadReport local;
  ReadReport& r = report ? *report : local;
  r = ReadReport{};
  if (bytes.empty()) throw InputError(source, "empty file");
  if (!options.object.empty() && format != "3mf")
    throw InputError(source, "a " + format + " file holds no named objects (asked for \"" + options.object + "\")");
  Mesh mesh;
  if (format == "stl")
    mesh = formats::parse_stl(bytes, source, r);
  else if (format == "obj")
    mesh = formats::parse_obj(bytes, source, r);
  else if (format == "off")
    mesh = formats::parse_off(bytes, source, r);
  else if (format == "ply")
    mesh = formats::parse_ply(bytes, source, r);
  else if (format == "3mf")
    mesh = formats::parse_3mf(bytes, source, r, options.object);
  else if (format == "gltf" || format == "glb")
    mesh = formats::parse_gltf(bytes, source, r, format == "glb");
  else
    throw InputError(source, "unknown mesh format \"" + format + "\" (expected " + mesh_format_list() + ")");
  if (mesh.num_vertices() == 0) throw InputError(source, "no vertices");
  size_t raw_faces = mesh.faces.size();
  if (raw_faces == 0) throw InputError(source, "no faces");
  clean_faces(mesh, r);
  if (mesh.faces.empty())
    throw InputError(source, "no faces left: all " + std::to_string(raw_faces) +
                                 " faces are degenerate (fewer than 3 distinct vertices)");
  return mesh;
}

Mesh read_mesh(const std::string& path, ReadReport* report, const ReadOptions& options) {
  const std::string ext = lower_extension(path);
  if (!is_mesh_format(ext))
    throw InputError(path, "unknown mesh format \"" + (ext.empty() ? "" : "." + ext) + "\" (expected " +
                               mesh_format_list() + ")");
  std::string bytes = read_input_file(path);
  return parse_mesh(bytes, ext, path, report, options);
}

std::string lower_extension(const std::string& path) {
  const auto slash = path.find_last_of('/');
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace mm
