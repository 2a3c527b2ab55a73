// OFF: "OFF" (or COFF/NOFF/CNOFF/STOFF..., whose extra per-vertex columns are ignored), then
// "nv nf ne", nv vertex lines and nf face lines "k i0 .. ik-1 [colour]". '#' starts a comment.
// The header counts are checked against the file size before anything is reserved.
#include <limits>

#include "meshio/formats.h"
#include "meshio/text_scan.h"

namespace mm::formats {

Mesh parse_off(std::string_view bytes, const std::string& source, ReadReport& report) {
  report.format = "off";
  scan::Lines lines(bytes);
  std::vector<std::string_view> tok;
  std::string_view line;
  auto fail = [&](const std::string& what) {
    throw InputError(source, "OFF line " + std::to_string(lines.number()) + ": " + what);
  };
  // Next line with content; false at end of file.
  auto next = [&]() {
    while (lines.next(line)) {
      scan::split(line, tok);
      if (!tok.empty()) return true;
    }
    return false;
  };
  if (!next()) throw InputError(source, "no content (missing OFF header)");
  std::string_view kw = tok[0];
  bool is_off = kw.size() >= 3 && kw.substr(kw.size() - 3) == "OFF";
  std::string_view prefix = is_off ? kw.substr(0, kw.size() - 3) : kw;
  if (is_off && (prefix.find('n') != std::string_view::npos || prefix.find('4') != std::string_view::npos))
    throw InputError(source, "unsupported OFF variant " + scan::quote(kw) + " (only 3D OFF)");
  if (!is_off || prefix.find_first_not_of("STCN") != std::string_view::npos)
    throw InputError(source, "missing OFF header: first word is " + scan::quote(kw));
  size_t first = 1;
  if (tok.size() > 1 && tok[1] == "BINARY") throw InputError(source, "binary OFF is not supported");
  if (tok.size() == 1) {
    if (!next()) throw InputError(source, "truncated: missing vertex/face counts after OFF header");
    first = 0;
  }
  if (tok.size() < first + 2) fail("bad OFF header: expected \"<vertices> <faces> <edges>\"");
  long long nv, nf;
  if (!scan::to_int64(tok[first], nv) || !scan::to_int64(tok[first + 1], nf))
    fail("bad OFF header: counts " + scan::quote(tok[first]) + " " + scan::quote(tok[first + 1]) +
         " are not integers");
  if (nv < 0 || nf < 0) fail("bad OFF header: negative count");
  // Each vertex line needs at least "0 0 0\n" (6 bytes), each face "3 0 1 2\n" (8).
  const long long size = static_cast<long long>(bytes.size());
  if (nv > std::numeric_limits<int>::max() || nf > std::numeric_limits<int>::max() ||
      nv * 6 + nf * 8 > size + 2)
    throw InputError(source, "absurd counts: header claims " + std::to_string(nv) + " vertices and " +
                                 std::to_string(nf) + " faces but the file has only " +
                                 std::to_string(size) + " bytes");
  Mesh m;
  m.points.resize(nv, 3);
  for (long long i = 0; i < nv; ++i) {
    if (!next())
      throw InputError(source, "truncated: header says " + std::to_string(nv) + " vertices, file ends after " +
                                   std::to_string(i));
    if (tok.size() < 3) fail("vertex " + std::to_string(i) + " has fewer than 3 coordinates");
    double xyz[3];
    for (int k = 0; k < 3; ++k)
      if (!scan::to_double(tok[k], xyz[k]))
        fail("malformed coordinate " + scan::quote(tok[k]) + " in vertex " + std::to_string(i));
    check_finite(xyz, source, "OFF line " + std::to_string(lines.number()) + " (vertex " + std::to_string(i) + ")");
    m.points.row(i) << xyz[0], xyz[1], xyz[2];
  }
  m.faces.reserve(static_cast<size_t>(nf));
  for (long long i = 0; i < nf; ++i) {
    if (!next())
      throw InputError(source, "truncated: header says " + std::to_string(nf) + " faces, file ends after " +
                                   std::to_string(i));
    long long k;
    if (!scan::to_int64(tok[0], k)) fail("malformed vertex count " + scan::quote(tok[0]) + " in face " + std::to_string(i));
    if (k < 1 || static_cast<size_t>(k) > tok.size() - 1)
      fail("face " + std::to_string(i) + " says " + std::to_string(k) + " vertices but lists " +
           std::to_string(tok.size() - 1) + " values");
    std::vector<int> f(static_cast<size_t>(k));
    for (long long j = 0; j < k; ++j) {
      long long v;
      std::string_view t = tok[static_cast<size_t>(j + 1)];
      if (!scan::to_int64(t, v)) fail("malformed vertex index " + scan::quote(t) + " in face " + std::to_string(i));
      if (v < 0 || v >= nv)
        fail("face " + std::to_string(i) + " index " + std::to_string(v) + " out of range (" +
             std::to_string(nv) + " vertices)");
      f[static_cast<size_t>(j)] = static_cast<int>(v);
    }
    m.faces.push_back(std::move(f));
  }
  if (next()) fail("unexpected content after the " + std::to_string(nf) + " faces of the header: " + scan::quote(tok[0]));
  return m;
}

}  // namespace mm::formats
