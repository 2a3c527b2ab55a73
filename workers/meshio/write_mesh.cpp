// Writers. Text formats print doubles with std::to_chars (shortest form that reads back to the
// identical double, independent of the C locale), so write/read round trips are exact.
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <system_error>

#include <Eigen/Geometry>

#include "meshio/formats.h"
#include "meshio/read_mesh.h"
#include "support/atomic_file.h"

namespace mm {
namespace {

void append_double(std::string& out, double d) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, d);
  out.append(buf, r.ptr);
}

void append_int(std::string& out, long long v) {
  char buf[24];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

// The shared structural check, its reason prefixed so the message says nothing was written.
void check_writable(const Mesh& mesh, const std::string& path) {
  try {
    check_mesh(mesh, path);
  } catch (const InputError& e) {
    throw InputError(path, "refusing to write: " + e.reason());
  }
}

std::string off_text(const Mesh& m) {
  std::string s = "OFF\n";
  append_int(s, m.num_vertices());
  s += ' ';
  append_int(s, m.num_faces());
  s += " 0\n";
  for (Eigen::Index i = 0; i < m.points.rows(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (k) s += ' ';
      append_double(s, m.points(i, k));
    }
    s += '\n';
  }
  for (const auto& f : m.faces) {
    append_int(s, static_cast<long long>(f.size()));
    for (int v : f) {
      s += ' ';
      append_int(s, v);
    }
    s += '\n';
  }
  return s;
}

std::string obj_text(const Mesh& m) {
  std::string s = "# meshmark\n";
  for (Eigen::Index i = 0; i < m.points.rows(); ++i) {
    s += 'v';
    for (int k = 0; k < 3; ++k) {
      s += ' ';
      append_double(s, m.points(i, k));
    }
    s += '\n';
  }
  for (const auto& f : m.faces) {
    s += 'f';
    for (int v : f) {
      s += ' ';
      append_int(s, v + 1);
    }
    s += '\n';
  }
  return s;
}

std::string ply_text(const Mesh& m) {
  size_t longest = 0;
  for (const auto& f : m.faces) longest = std::max(longest, f.size());
  std::string s = "ply\nformat ascii 1.0\ncomment meshmark\nelement vertex ";
  append_int(s, m.num_vertices());
  s += "\nproperty double x\nproperty double y\nproperty double z\nelement face ";
  append_int(s, m.num_faces());
  s += longest < 256 ? "\nproperty list uchar int vertex_indices\n" : "\nproperty list uint int vertex_indices\n";
  s += "end_header\n";
  std::string body = off_text(m);
  // The OFF body after its two header lines is exactly PLY ASCII's vertex and face lines.
  size_t second = body.find('\n', body.find('\n') + 1);
  s.append(body, second + 1, std::string::npos);
  return s;
}

void put32(std::string& s, uint32_t u) {
  for (int k = 0; k < 4; ++k) s += static_cast<char>((u >> (8 * k)) & 0xff);
}
void putf(std::string& s, float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  put32(s, u);
}

std::string stl_bytes(const Mesh& m, const std::string& path) {
  size_t tris = 0;
  for (const auto& f : m.faces) tris += f.size() - 2;
  if (tris > 0xffffffffull) throw InputError(path, "too many triangles for binary STL");
  std::string s(80, '\0');
  const char* title = "meshmark binary STL";
  std::memcpy(s.data(), title, std::strlen(title));
  put32(s, static_cast<uint32_t>(tris));
  s.reserve(84 + 50 * tris);
  for (const auto& f : m.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) {  // fan triangulation keeps the orientation
      Eigen::Vector3d a = m.points.row(f[0]), b = m.points.row(f[k]), c = m.points.row(f[k + 1]);
      Eigen::Vector3d n = (b - a).cross(c - a);
      double len = n.norm();
      if (len > 0) n /= len;
      for (int i = 0; i < 3; ++i) putf(s, static_cast<float>(n[i]));
      for (const auto* p : {&a, &b, &c})
        for (int i = 0; i < 3; ++i) putf(s, static_cast<float>((*p)[i]));
      s += '\0';
      s += '\0';
    }
  return s;
}

// Readers never see a half-written mesh (support/atomic_file.h).
void atomic_write(const std::string& path, const std::string& bytes) {
  try {
    support::write_file_atomic(path, bytes);
  } catch (const std::system_error& e) {
    throw InputError(path, e.what());
  }
}

}  // namespace

std::string mesh_file_bytes(const Mesh& mesh, const std::string& path, const WriteOptions& options) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext.empty() || !is_mesh_format(ext.substr(1)))
    throw InputError(path, "unknown mesh format \"" + ext + "\" (expected " + mesh_format_list() + ")");
  check_writable(mesh, path);
  return ext == ".stl" ? stl_bytes(mesh, path)
         : ext == ".obj" ? obj_text(mesh)
         : ext == ".off" ? off_text(mesh)
         : ext == ".ply" ? ply_text(mesh)
         : ext == ".3mf" ? formats::three_mf_bytes(mesh, options.unit, path, options.object)
                         : formats::gltf_bytes(mesh, path, ext == ".glb", options.draco_bits);
}

void write_mesh(const Mesh& mesh, const std::string& path, const WriteOptions& options) {
  atomic_write(path, mesh_file_bytes(mesh, path, options));
}

std::string shortest_text(double d) {
  std::string s;
  append_double(s, d);
  return s;
}

std::string three_mf_build_bytes(const std::vector<std::pair<std::string, Mesh>>& objects, const std::string& unit) {
  return formats::three_mf_bytes(objects, unit, "3MF build");
}

}  // namespace mm
