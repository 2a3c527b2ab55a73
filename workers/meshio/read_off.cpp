// OFF: "OFF" (or COFF/NOFF/CNOFF/STOFF..., whose extra per-vertex columns are ignored), then
// "nv nf ne", nv vertex lines and nf face lines "k i0 .. ik-1 [colour]". '#' starts a comment.
// Binary OFF (Geomview): the header line "OFF BINARY", then big-endian int32 nv nf ne, nv
// vertices of float32 (x y z, then normal, colour and texture columns as the prefix says), and nf
// faces "int32 k, k int32 indices, int32 m, m float32 colour values".
// The header counts are checked against the file size before anything is reserved.
#include <cstdint>
#include <cstring>
#include <limits>

#include "meshio/formats.h"
#include "meshio/text_scan.h"

namespace mm::formats {
namespace {

// Big-endian 32-bit words, every read checked against the end.
class BigEndianWords {
 public:
  BigEndianWords(std::string_view bytes, const std::string& source) : bytes_(bytes), source_(source) {}
  std::uint32_t word(const char* what) {
    if (bytes_.size() - at_ < 4)
      throw InputError(source_, "truncated: binary OFF ends inside " + std::string(what) + " at byte " +
                                    std::to_string(at_));
    const auto* p = reinterpret_cast<const unsigned char*>(bytes_.data() + at_);
    at_ += 4;
    return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
  }
  std::int32_t integer(const char* what) { return static_cast<std::int32_t>(word(what)); }
  float real(const char* what) {
    const std::uint32_t w = word(what);
    float f;
    std::memcpy(&f, &w, sizeof f);
    return f;
  }
  std::size_t left() const { return bytes_.size() - at_; }
  std::string_view rest() const { return bytes_.substr(at_); }

 private:
  std::string_view bytes_;
  std::size_t at_ = 0;
  const std::string& source_;
};

Mesh parse_off_binary(std::string_view data, std::string_view prefix, const std::string& source) {
  BigEndianWords in(data, source);
  const long long nv = in.integer("the vertex count"), nf = in.integer("the face count");
  in.integer("the edge count");
  if (nv < 0 || nf < 0) throw InputError(source, "bad binary OFF header: negative count");
  // Per vertex x y z, a normal (N), a colour (C: RGBA) and texture coordinates (ST).
  const long long columns = 3 + (prefix.find('N') != std::string_view::npos ? 3 : 0) +
                            (prefix.find('C') != std::string_view::npos ? 4 : 0) +
                            (prefix.find("ST") != std::string_view::npos ? 2 : 0);
  // Each face needs at least its count, one index and its colour count (12 bytes).
  if (nv * columns * 4 + nf * 12 > static_cast<long long>(in.left()))
    throw InputError(source, "absurd counts: header claims " + std::to_string(nv) + " vertices and " +
                                 std::to_string(nf) + " faces but the binary data has only " +
                                 std::to_string(in.left()) + " bytes");
  Mesh m;
  m.points.resize(nv, 3);
  for (long long i = 0; i < nv; ++i) {
    double xyz[3];
    for (double& x : xyz) x = in.real("a vertex");
    for (long long c = 3; c < columns; ++c) in.real("a vertex");
    check_finite(xyz, source, "binary OFF vertex " + std::to_string(i));
    m.points.row(i) << xyz[0], xyz[1], xyz[2];
  }
  m.faces.reserve(static_cast<std::size_t>(nf));
  for (long long i = 0; i < nf; ++i) {
    const long long k = in.integer("a face");
    if (k < 1 || k * 4 > static_cast<long long>(in.left()))
      throw InputError(source, "binary OFF face " + std::to_string(i) + " says " + std::to_string(k) +
                                   " vertices, which the file cannot hold");
    std::vector<int> f(static_cast<std::size_t>(k));
    for (auto& v : f) {
      const long long index = in.integer("a face");
      if (index < 0 || index >= nv)
        throw InputError(source, "binary OFF face " + std::to_string(i) + " index " + std::to_string(index) +
                                     " out of range (" + std::to_string(nv) + " vertices)");
      v = static_cast<int>(index);
    }
    const long long colours = in.integer("a face's colour count");
    if (colours < 0 || colours > 4)
      throw InputError(source, "binary OFF face " + std::to_string(i) + " has " + std::to_string(colours) +
                                   " colour values (at most 4)");
    for (long long c = 0; c < colours; ++c) in.real("a face's colour");
    m.faces.push_back(std::move(f));
  }
  if (in.rest().find_first_not_of(" \t\r\n") != std::string_view::npos)
    throw InputError(source, std::to_string(in.left()) + " bytes after the " + std::to_string(nf) +
                                 " faces of the binary OFF header");
  return m;
}

}  // namespace

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
  if (tok.size() > 1 && tok[1] == "BINARY") {
    if (tok.size() > 2) fail("unexpected " + scan::quote(tok[2]) + " after \"BINARY\"");
    if (lines.offset() >= bytes.size()) throw InputError(source, "truncated: binary OFF has no data after its header");
    report.format = "off-binary";
    return parse_off_binary(bytes.substr(lines.offset()), prefix, source);
  }
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
