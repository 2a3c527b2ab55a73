#include "codec/rice.h"

#include <algorithm>

namespace mm::codec_detail {

void BitWriter::bits(std::uint64_t value, int count) {
  for (int i = 0; i < count; ++i) {
    if (used_ == 8) {
      bytes_.push_back(0);
      used_ = 0;
    }
    if ((value >> i) & 1) bytes_.back() |= static_cast<std::uint8_t>(1u << used_);
    ++used_;
  }
}

void BitWriter::rice(std::uint64_t value, int k) {
  const std::uint64_t q = value >> k;
  for (std::uint64_t i = 0; i < q; ++i) bits(1, 1);
  bits(0, 1);
  bits(value, k);
}

std::uint64_t BitReader::bits(int count, const char* what) {
  if (pos_ + static_cast<std::size_t>(count) > size_ * 8)
    errors_.fail(std::string("truncated while reading ") + what);
  std::uint64_t v = 0;
  for (int i = 0; i < count; ++i, ++pos_)
    v |= static_cast<std::uint64_t>((data_[pos_ / 8] >> (pos_ % 8)) & 1) << i;
  return v;
}

std::uint64_t BitReader::rice(int k, const char* what) {
  std::uint64_t q = 0;
  while (bits(1, what)) {
    if (++q > kMaxRiceQuotient) errors_.fail(std::string("Rice quotient too long in ") + what);
  }
  return (q << k) | bits(k, what);
}

void BitReader::expect_end(const char* what) {
  if ((pos_ + 7) / 8 != size_) errors_.fail(std::string("unexpected trailing bytes in ") + what);
  if (pos_ % 8 && (data_[pos_ / 8] >> (pos_ % 8)) != 0)
    errors_.fail(std::string("padding bits set in ") + what);
}

int best_rice_parameter(const std::vector<std::uint64_t>& values) {
  const std::uint64_t top = values.empty() ? 0 : *std::max_element(values.begin(), values.end());
  int best = kMaxRiceParameter;
  std::uint64_t best_bits = ~0ull;
  for (int k = 0; k <= kMaxRiceParameter; ++k) {
    if ((top >> k) > kMaxRiceQuotient) continue;
    std::uint64_t total = 0;
    for (std::uint64_t v : values) total += (v >> k) + 1 + static_cast<std::uint64_t>(k);
    if (total < best_bits) {
      best_bits = total;
      best = k;
    }
  }
  return best;
}

}  // namespace mm::codec_detail
