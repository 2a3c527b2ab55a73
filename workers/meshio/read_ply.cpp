// PLY: ASCII, binary_little_endian and binary_big_endian. Reads element "vertex" (properties
// x, y, z of any scalar type) and element "face" (list property vertex_indices or
// vertex_index); every other element and property is parsed and skipped. Element counts are
// checked against the bytes that follow the header before anything is reserved.
#include <cstdint>
#include <cstring>
#include <limits>

#include "meshio/formats.h"
#include "meshio/text_scan.h"

namespace mm::formats {
namespace {

enum class Type { I8, U8, I16, U16, I32, U32, F32, F64 };

bool type_from(std::string_view s, Type& t) {
  if (s == "char" || s == "int8") t = Type::I8;
  else if (s == "uchar" || s == "uint8") t = Type::U8;
  else if (s == "short" || s == "int16") t = Type::I16;
  else if (s == "ushort" || s == "uint16") t = Type::U16;
  else if (s == "int" || s == "int32") t = Type::I32;
  else if (s == "uint" || s == "uint32") t = Type::U32;
  else if (s == "float" || s == "float32") t = Type::F32;
  else if (s == "double" || s == "float64") t = Type::F64;
  else return false;
  return true;
}
size_t type_size(Type t) {
  switch (t) {
    case Type::I8: case Type::U8: return 1;
    case Type::I16: case Type::U16: return 2;
    case Type::I32: case Type::U32: case Type::F32: return 4;
    case Type::F64: return 8;
  }
  return 8;
}
bool is_integer(Type t) { return t != Type::F32 && t != Type::F64; }

struct Property {
  std::string name;
  Type type = Type::F32;
  bool is_list = false;
  Type count_type = Type::U8;
};
struct Element {
  std::string name;
  long long count = 0;
  std::vector<Property> props;
  int line = 0;
};

// Reads scalar values one at a time from the body, ASCII or binary, reporting truncation.
class Body {
 public:
  Body(std::string_view data, int format, const std::string& source, int first_line)
      : data_(data), format_(format), source_(source), tok_(data, 0, first_line) {}
  // Where we are, for messages.
  std::string where(const Element& e, long long i) const {
    return "element \"" + e.name + "\" " + std::to_string(i);
  }
  double value(Type t, const std::string& ctx) {
    if (format_ == 0) {
      std::string_view s = tok_.next();
      if (s.empty()) throw InputError(source_, "truncated: PLY data ends in " + ctx);
      if (is_integer(t)) {
        long long v;
        if (!scan::to_int64(s, v)) throw InputError(source_, "PLY line " + std::to_string(tok_.line()) +
                                                              ": malformed integer " + scan::quote(s) + " in " + ctx);
        return static_cast<double>(v);
      }
      double d;
      if (!scan::to_double(s, d)) throw InputError(source_, "PLY line " + std::to_string(tok_.line()) +
                                                             ": malformed number " + scan::quote(s) + " in " + ctx);
      return d;
    }
    size_t n = type_size(t);
    if (pos_ + n > data_.size()) throw InputError(source_, "truncated: PLY data ends in " + ctx);
    unsigned char b[8];
    std::memcpy(b, data_.data() + pos_, n);
    pos_ += n;
    bool file_le = format_ == 1;
    uint16_t probe = 1;
    bool host_le = *reinterpret_cast<unsigned char*>(&probe) == 1;
    if (file_le != host_le)
      for (size_t k = 0; k < n / 2; ++k) std::swap(b[k], b[n - 1 - k]);
    switch (t) {
      case Type::I8: { int8_t v; std::memcpy(&v, b, 1); return v; }
      case Type::U8: return b[0];
      case Type::I16: { int16_t v; std::memcpy(&v, b, 2); return v; }
      case Type::U16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
      case Type::I32: { int32_t v; std::memcpy(&v, b, 4); return v; }
      case Type::U32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
      case Type::F32: { float v; std::memcpy(&v, b, 4); return v; }
      case Type::F64: { double v; std::memcpy(&v, b, 8); return v; }
    }
    return 0;
  }
  bool at_end() {
    if (format_ != 0)  // some writers end binary files with a newline
      return data_.find_first_not_of(" \t\r\n", pos_) == std::string_view::npos;
    return tok_.next().empty();
  }

 private:
  std::string_view data_;
  int format_;  // 0 ascii, 1 little endian, 2 big endian
  const std::string& source_;
  scan::Tokens tok_;
  size_t pos_ = 0;
};

}  // namespace

Mesh parse_ply(std::string_view bytes, const std::string& source, ReadReport& report) {
  scan::Lines lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tok;
  auto fail = [&](const std::string& what) {
    throw InputError(source, "PLY header line " + std::to_string(lines.number()) + ": " + what);
  };
  if (!lines.next(line) || line != "ply") throw InputError(source, "missing PLY header (first line is not \"ply\")");
  int format = -1;
  std::vector<Element> elements;
  size_t body_start = std::string_view::npos;
  size_t consumed = 0;
  while (lines.next(line)) {
    consumed = static_cast<size_t>(line.data() - bytes.data()) + line.size();
    scan::split(line, tok);
    if (tok.empty()) continue;
    if (tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") {
      body_start = consumed;
      if (body_start < bytes.size() && bytes[body_start] == '\r') ++body_start;
      if (body_start < bytes.size() && bytes[body_start] == '\n') ++body_start;
      break;
    }
    if (tok[0] == "format") {
      if (tok.size() < 3) fail("incomplete format line");
      if (tok[1] == "ascii") format = 0;
      else if (tok[1] == "binary_little_endian") format = 1;
      else if (tok[1] == "binary_big_endian") format = 2;
      else fail("unknown format " + scan::quote(tok[1]));
    } else if (tok[0] == "element") {
      long long c;
      if (tok.size() != 3 || !scan::to_int64(tok[2], c) || c < 0) fail("malformed element line");
      elements.push_back({std::string(tok[1]), c, {}, lines.number()});
    } else if (tok[0] == "property") {
      if (elements.empty()) fail("property before any element");
      Property p;
      if (tok.size() == 5 && tok[1] == "list") {
        p.is_list = true;
        if (!type_from(tok[2], p.count_type) || !type_from(tok[3], p.type)) fail("unknown list property type");
        if (!is_integer(p.count_type)) fail("list count type must be an integer type");
        p.name = std::string(tok[4]);
      } else if (tok.size() == 3) {
        if (!type_from(tok[1], p.type)) fail("unknown property type " + scan::quote(tok[1]));
        p.name = std::string(tok[2]);
      } else {
        fail("malformed property line");
      }
      elements.back().props.push_back(p);
    } else {
      fail("unknown header keyword " + scan::quote(tok[0]));
    }
  }
  if (body_start == std::string_view::npos) throw InputError(source, "truncated: PLY header has no end_header");
  if (format < 0) throw InputError(source, "PLY header has no format line");
  report.format = format == 0 ? "ply-ascii" : "ply-binary";

  // Refuse counts the remaining bytes cannot hold (ASCII: at least 2 bytes per value).
  const long double available = static_cast<long double>(bytes.size() - body_start) + 1;
  long double needed = 0;
  const Element* vertex = nullptr;
  const Element* face = nullptr;
  for (const auto& e : elements) {
    if (e.count > std::numeric_limits<int>::max())
      throw InputError(source, "absurd count: element \"" + e.name + "\" claims " + std::to_string(e.count) + " items");
    size_t per = 0;
    for (const auto& p : e.props) per += format == 0 ? 2 : type_size(p.is_list ? p.count_type : p.type);
    needed += static_cast<long double>(e.count) * static_cast<long double>(std::max<size_t>(per, 1));
    if (e.name == "vertex") vertex = &e;
    if (e.name == "face") face = &e;
  }
  if (needed > available)
    throw InputError(source, "absurd counts: the header's elements need at least " +
                                 std::to_string(static_cast<long long>(needed)) + " bytes but the file has " +
                                 std::to_string(bytes.size() - body_start) + " after the header");
  if (!vertex) throw InputError(source, "PLY has no \"vertex\" element");
  int ix = -1, iy = -1, iz = -1, ifl = -1;
  for (size_t k = 0; k < vertex->props.size(); ++k) {
    const auto& p = vertex->props[k];
    if (p.is_list) continue;
    if (p.name == "x") ix = static_cast<int>(k);
    if (p.name == "y") iy = static_cast<int>(k);
    if (p.name == "z") iz = static_cast<int>(k);
  }
  if (ix < 0 || iy < 0 || iz < 0) throw InputError(source, "PLY vertex element lacks x, y or z");
  if (!face) throw InputError(source, "no faces: PLY has no \"face\" element");
  for (size_t k = 0; k < face->props.size(); ++k)
    if (face->props[k].is_list && (face->props[k].name == "vertex_indices" || face->props[k].name == "vertex_index"))
      ifl = static_cast<int>(k);
  if (ifl < 0) throw InputError(source, "PLY face element lacks a vertex_indices list");
  if (!is_integer(face->props[static_cast<size_t>(ifl)].type))
    throw InputError(source, "PLY face indices must be integers");

  Mesh m;
  m.points.resize(vertex->count, 3);
  m.faces.reserve(static_cast<size_t>(face->count));
  Body body(bytes.substr(body_start), format, source, lines.number() + 1);
  for (const auto& e : elements) {
    const bool is_v = &e == vertex, is_f = &e == face;
    for (long long i = 0; i < e.count; ++i) {
      const std::string ctx = body.where(e, i);
      double xyz[3] = {0, 0, 0};
      for (size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        if (!p.is_list) {
          double v = body.value(p.type, ctx);
          if (is_v && static_cast<int>(k) == ix) xyz[0] = v;
          if (is_v && static_cast<int>(k) == iy) xyz[1] = v;
          if (is_v && static_cast<int>(k) == iz) xyz[2] = v;
          continue;
        }
        double cnt = body.value(p.count_type, ctx);
        if (cnt < 0 || cnt > 1e6) throw InputError(source, "absurd list length " + std::to_string(cnt) + " in " + ctx);
        const bool indices = is_f && static_cast<int>(k) == ifl;
        std::vector<int> f;
        if (indices) f.reserve(static_cast<size_t>(cnt));
        for (long long j = 0; j < static_cast<long long>(cnt); ++j) {
          double v = body.value(p.type, ctx);
          if (!indices) continue;
          if (v < 0 || v >= static_cast<double>(vertex->count))
            throw InputError(source, "face " + std::to_string(i) + " index " + std::to_string(static_cast<long long>(v)) +
                                         " out of range (" + std::to_string(vertex->count) + " vertices)");
          f.push_back(static_cast<int>(v));
        }
        if (indices) m.faces.push_back(std::move(f));
      }
      if (is_v) {
        check_finite(xyz, source, "PLY vertex " + std::to_string(i));
        m.points.row(i) << xyz[0], xyz[1], xyz[2];
      }
    }
  }
  if (!body.at_end()) throw InputError(source, "unexpected data after the last PLY element");
  return m;
}

}  // namespace mm::formats
