// Wavefront OBJ: "v x y z [w | r g b]" and "f i[/t][/n] ..." (1-based; negative = relative to
// the latest vertex). Texture coordinates, normals, groups, materials, lines and points are
// ignored; any other malformed statement is an error with its line number.
#include <limits>

#include "meshio/formats.h"
#include "meshio/text_scan.h"

namespace mm::formats {

Mesh parse_obj(std::string_view bytes, const std::string& source, ReadReport& report) {
  report.format = "obj";
  scan::Lines lines(bytes);
  std::vector<std::string_view> tok;
  std::string_view line;
  auto fail = [&](const std::string& what) {
    throw InputError(source, "OBJ line " + std::to_string(lines.number()) + ": " + what);
  };
  std::vector<double> pts;
  std::vector<std::vector<int>> faces;
  // Faces may reference vertices defined later; indices are checked once all are known.
  std::vector<int> face_line;
  while (lines.next(line)) {
    scan::split(line, tok);
    if (tok.empty()) continue;
    std::string_view kw = tok[0];
    if (kw == "v") {
      if (tok.size() < 4) fail("vertex with fewer than 3 coordinates");
      double xyz[3];
      for (int k = 0; k < 3; ++k)
        if (!scan::to_double(tok[static_cast<size_t>(k + 1)], xyz[k]))
          fail("malformed coordinate " + scan::quote(tok[static_cast<size_t>(k + 1)]));
      for (size_t k = 4; k < tok.size(); ++k) {
        double extra;
        if (!scan::to_double(tok[k], extra)) fail("malformed value " + scan::quote(tok[k]) + " in vertex");
      }
      check_finite(xyz, source, "OBJ line " + std::to_string(lines.number()));
      if (pts.size() / 3 >= static_cast<size_t>(std::numeric_limits<int>::max())) fail("too many vertices");
      pts.insert(pts.end(), xyz, xyz + 3);
    } else if (kw == "f") {
      if (tok.size() < 4) fail("face with fewer than 3 vertices");
      std::vector<int> f;
      f.reserve(tok.size() - 1);
      long long nv = static_cast<long long>(pts.size() / 3);
      for (size_t k = 1; k < tok.size(); ++k) {
        std::string_view t = tok[k];
        std::string_view idx = t.substr(0, t.find('/'));
        long long v;
        if (!scan::to_int64(idx, v) || v == 0) fail("malformed face token " + scan::quote(t));
        if (v < 0) {
          v = nv + v;  // -1 is the latest vertex
          if (v < 0) fail("relative index " + std::string(idx) + " reaches before the first vertex");
        } else {
          v -= 1;
        }
        if (v > std::numeric_limits<int>::max()) fail("face index " + std::string(idx) + " out of range");
        f.push_back(static_cast<int>(v));
      }
      faces.push_back(std::move(f));
      face_line.push_back(lines.number());
    } else if (kw == "vt" || kw == "vn" || kw == "vp" || kw == "g" || kw == "o" || kw == "s" ||
               kw == "usemtl" || kw == "mtllib" || kw == "l" || kw == "p" || kw == "cstype" ||
               kw == "deg" || kw == "curv" || kw == "surf" || kw == "parm" || kw == "end" ||
               kw == "mg" || kw == "lod" || kw == "shadow_obj" || kw == "trace_obj") {
      continue;
    } else {
      fail("unknown statement " + scan::quote(kw));
    }
  }
  const long long nv = static_cast<long long>(pts.size() / 3);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int v : faces[i])
      if (v >= nv)
        throw InputError(source, "OBJ line " + std::to_string(face_line[i]) + ": face index " +
                                     std::to_string(v + 1) + " out of range (" + std::to_string(nv) +
                                     " vertices)");
  Mesh m;
  m.points.resize(nv, 3);
  for (size_t i = 0; i < pts.size(); ++i) m.points.data()[i] = pts[i];
  m.faces = std::move(faces);
  return m;
}

}  // namespace mm::formats
