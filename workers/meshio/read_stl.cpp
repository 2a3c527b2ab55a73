// STL: binary (80-byte header, uint32 count, 50 bytes per triangle) or ASCII
// (solid/facet/outer loop/vertex). STL is a triangle soup: corners with exactly equal
// coordinates are welded into one vertex, numbered in order of first appearance.
#include <cstdint>
#include <cstring>
#include <unordered_map>

#include "meshio/formats.h"
#include "meshio/text_scan.h"

namespace mm::formats {
namespace {

struct Key {
  double x, y, z;
  bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct KeyHash {
  size_t operator()(const Key& k) const {
    uint64_t h = 1469598103934665603ull;
    for (double d : {k.x, k.y, k.z}) {
      uint64_t b;
      std::memcpy(&b, &d, 8);
      h = (h ^ b) * 1099511628211ull;
      h ^= h >> 29;
    }
    return static_cast<size_t>(h);
  }
};

class Welder {
 public:
  explicit Welder(size_t expected) { map_.reserve(expected); pts_.reserve(expected * 3); }
  int add(double x, double y, double z) {
    ++corners_;
    // -0.0 and 0.0 compare equal but hash differently: normalise the sign of zero.
    Key k{x + 0.0, y + 0.0, z + 0.0};
    auto [it, inserted] = map_.try_emplace(k, static_cast<int>(map_.size()));
    if (inserted) pts_.insert(pts_.end(), {k.x, k.y, k.z});
    return it->second;
  }
  Mesh finish(std::vector<std::vector<int>> faces, ReadReport& report) {
    Mesh m;
    m.points.resize(static_cast<Eigen::Index>(map_.size()), 3);
    for (size_t i = 0; i < pts_.size(); ++i) m.points.data()[i] = pts_[i];
    m.faces = std::move(faces);
    report.welded_vertices = static_cast<int>(corners_ - map_.size());
    return m;
  }

 private:
  std::unordered_map<Key, int, KeyHash> map_;
  std::vector<double> pts_;
  size_t corners_ = 0;
};

uint32_t le32(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}
float lefloat(const unsigned char* p) {
  uint32_t u = le32(p);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

Mesh parse_binary(std::string_view bytes, const std::string& source, ReadReport& report) {
  report.format = "stl-binary";
  auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  uint64_t n = le32(p + 80);
  if (n == 0) throw InputError(source, "no faces: binary STL header says 0 triangles");
  Welder w(static_cast<size_t>(n));
  std::vector<std::vector<int>> faces;
  faces.reserve(static_cast<size_t>(n));
  for (uint64_t t = 0; t < n; ++t) {
    const unsigned char* q = p + 84 + 50 * t + 12;  // skip the stored normal
    std::vector<int> f(3);
    for (int c = 0; c < 3; ++c) {
      double xyz[3] = {lefloat(q + 12 * c), lefloat(q + 12 * c + 4), lefloat(q + 12 * c + 8)};
      check_finite(xyz, source, "triangle " + std::to_string(t) + " corner " + std::to_string(c));
      f[static_cast<size_t>(c)] = w.add(xyz[0], xyz[1], xyz[2]);
    }
    faces.push_back(std::move(f));
  }
  return w.finish(std::move(faces), report);
}

Mesh parse_ascii(std::string_view bytes, const std::string& source, ReadReport& report) {
  report.format = "stl-ascii";
  scan::Tokens tok(bytes);
  auto fail = [&](const std::string& what) {
    throw InputError(source, "ASCII STL line " + std::to_string(tok.line()) + ": " + what);
  };
  auto expect = [&](const char* word) {
    std::string_view t = tok.next();
    if (t != word) fail(std::string("expected \"") + word + "\", found " + (t.empty() ? "end of file" : scan::quote(t)));
  };
  auto number = [&](const char* what) {
    std::string_view t = tok.next();
    double d;
    if (t.empty()) fail(std::string("truncated: file ends inside ") + what);
    if (!scan::to_double(t, d)) fail(std::string("malformed number ") + scan::quote(t) + " in " + what);
    return d;
  };
  // An ASCII STL is text; refuse early rather than tokenising binary garbage.
  // Welding capacity: about 250 bytes per facet in practice; guess from size.
  Welder w(bytes.size() / 250 + 16);
  std::vector<std::vector<int>> faces;
  bool any_solid = false;
  for (;;) {
    std::string_view t = tok.next();
    if (t.empty()) break;
    if (t != "solid") fail("expected \"solid\", found " + scan::quote(t));
    any_solid = true;
    tok.rest_of_line();  // the solid's name
    for (;;) {
      t = tok.next();
      if (t.empty()) fail("truncated: missing \"endsolid\"");
      if (t == "endsolid") {
        tok.rest_of_line();
        break;
      }
      if (t != "facet") fail("expected \"facet\" or \"endsolid\", found " + scan::quote(t));
      expect("normal");
      for (int k = 0; k < 3; ++k) number("facet normal");  // recomputed from the corners
      expect("outer");
      expect("loop");
      std::vector<int> f;
      for (;;) {
        t = tok.next();
        if (t == "endloop") break;
        if (t.empty()) fail("truncated: file ends inside a facet");
        if (t != "vertex") fail("expected \"vertex\" or \"endloop\", found " + scan::quote(t));
        double xyz[3];
        for (double& c : xyz) c = number("vertex");
        check_finite(xyz, source, "ASCII STL line " + std::to_string(tok.line()));
        f.push_back(w.add(xyz[0], xyz[1], xyz[2]));
      }
      if (f.size() < 3) fail("facet with " + std::to_string(f.size()) + " vertices (needs 3)");
      expect("endfacet");
      faces.push_back(std::move(f));
    }
  }
  if (!any_solid) throw InputError(source, "no STL content");
  return w.finish(std::move(faces), report);
}

bool looks_like_text(std::string_view bytes) {
  size_t n = std::min<size_t>(bytes.size(), 4096);
  for (size_t i = 0; i < n; ++i) {
    unsigned char c = static_cast<unsigned char>(bytes[i]);
    if (c < 9 || (c > 13 && c < 32) || c == 127) return false;
  }
  return true;
}

}  // namespace

Mesh parse_stl(std::string_view bytes, const std::string& source, ReadReport& report) {
  // Binary when the size matches the header's count exactly (binary headers may start with
  // "solid" too); ASCII when it is text starting with "solid"; otherwise a broken binary file.
  bool size_matches = false;
  uint64_t n = 0;
  if (bytes.size() >= 84) {
    n = le32(reinterpret_cast<const unsigned char*>(bytes.data()) + 80);
    size_matches = 84 + 50 * n == bytes.size();
  }
  if (size_matches) return parse_binary(bytes, source, report);
  size_t b = bytes.find_first_not_of(" \t\r\n");
  bool starts_solid = b != std::string_view::npos && bytes.substr(b, 5) == "solid";
  if (starts_solid && looks_like_text(bytes)) return parse_ascii(bytes, source, report);
  if (bytes.size() < 84)
    throw InputError(source, "truncated binary STL: " + std::to_string(bytes.size()) +
                                 " bytes, shorter than the 84-byte header");
  throw InputError(source, "binary STL size mismatch: header says " + std::to_string(n) +
                               " triangles (" + std::to_string(84 + 50 * n) + " bytes), file has " +
                               std::to_string(bytes.size()) + " bytes (truncated or not an STL)");
}

}  // namespace mm::formats
