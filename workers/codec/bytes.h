// Byte-level helpers shared by the stream and connectivity coders: little-endian values,
// canonical LEB128 varints, zigzag signed mapping, and a bounds-checked reader whose failures
// are InputErrors naming the source and the field being read.
#pragma once
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "meshio/mesh.h"

namespace mm::codec_detail {

class Writer {
 public:
  std::vector<std::uint8_t> bytes;
  void u8(std::uint8_t v) { bytes.push_back(v); }
  void f64(double v) {
    std::uint64_t u;
    std::memcpy(&u, &v, 8);
    for (int i = 0; i < 8; ++i) bytes.push_back(static_cast<std::uint8_t>(u >> (8 * i)));
  }
  void varint(std::uint64_t v) {
    while (v >= 0x80) {
      bytes.push_back(static_cast<std::uint8_t>(v | 0x80));
      v >>= 7;
    }
    bytes.push_back(static_cast<std::uint8_t>(v));
  }
  void raw(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    bytes.insert(bytes.end(), b, b + n);
  }
};

// Bounds-checked reader: every read names what it was reading when the bytes run out.
class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size, const std::string& source, const char* where)
      : p_(data), end_(data + size), source_(source), where_(where) {}
  std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }
  [[noreturn]] void fail(const std::string& reason) const {
    throw InputError(source_, std::string(where_) + ": " + reason);
  }
  void need(std::size_t n, const char* what) const {
    if (remaining() < n) fail(std::string("truncated while reading ") + what);
  }
  std::uint8_t u8(const char* what) {
    need(1, what);
    return *p_++;
  }
  double f64(const char* what) {
    need(8, what);
    std::uint64_t u = 0;
    for (int i = 0; i < 8; ++i) u |= static_cast<std::uint64_t>(p_[i]) << (8 * i);
    p_ += 8;
    double v;
    std::memcpy(&v, &u, 8);
    return v;
  }
  // Canonical (shortest) LEB128 no larger than max.
  std::uint64_t varint(const char* what, std::uint64_t max) {
    std::uint64_t v = 0;
    for (int shift = 0;; shift += 7) {
      if (shift > 63) fail(std::string("overlong varint in ") + what);
      const std::uint8_t b = u8(what);
      const std::uint64_t part = static_cast<std::uint64_t>(b & 0x7F);
      if (shift == 63 && part > 1) fail(std::string("varint overflow in ") + what);
      v |= part << shift;
      if (!(b & 0x80)) {
        if (b == 0 && shift > 0) fail(std::string("non-canonical varint in ") + what);
        break;
      }
    }
    if (v > max)
      fail(std::string(what) + " " + std::to_string(v) + " exceeds the limit " + std::to_string(max));
    return v;
  }
  const std::uint8_t* bytes(std::size_t n, const char* what) {
    need(n, what);
    const std::uint8_t* r = p_;
    p_ += n;
    return r;
  }
  const std::uint8_t* position() const { return p_; }

 private:
  const std::uint8_t* p_;
  const std::uint8_t* end_;
  const std::string& source_;
  const char* where_;
};

inline std::uint64_t zigzag(std::int64_t v) {
  return (static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63);
}
inline std::int64_t unzigzag(std::uint64_t u) {
  return static_cast<std::int64_t>(u >> 1) ^ -static_cast<std::int64_t>(u & 1);
}

}  // namespace mm::codec_detail
