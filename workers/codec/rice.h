// Golomb-Rice codes for the coordinate residuals: a value u is its quotient u >> k in unary
// (that many 1 bits, then a 0) followed by its k low bits, least significant first. Residuals
// of a good prediction are roughly geometric, for which Rice codes are near optimal, and unlike
// byte varints they waste no bits that zstd could not recover. Bits fill bytes from the least
// significant bit up.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "codec/bytes.h"

namespace mm::codec_detail {

// Longest unary quotient a stream may hold; the encoder picks k so that no value needs more.
// It bounds the bits per value (and so the decoder's work per byte).
constexpr std::uint32_t kMaxRiceQuotient = 64;
constexpr int kMaxRiceParameter = 30;

class BitWriter {
 public:
  void bits(std::uint64_t value, int count);
  void rice(std::uint64_t value, int k);
  // Bytes so far; the last byte is padded with zero bits.
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
  int used_ = 8;  // bits used in the last byte
};

class BitReader {
 public:
  BitReader(const std::uint8_t* data, std::size_t size, Reader& errors)
      : data_(data), size_(size), errors_(errors) {}
  std::uint64_t bits(int count, const char* what);
  std::uint64_t rice(int k, const char* what);
  // Fails unless every whole byte was used and the padding bits of the last one are zero.
  void expect_end(const char* what);

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;  // in bits
  Reader& errors_;
};

// The k in [0, kMaxRiceParameter] giving the fewest bits for the values with every quotient at
// most kMaxRiceQuotient.
int best_rice_parameter(const std::vector<std::uint64_t>& values);

}  // namespace mm::codec_detail
