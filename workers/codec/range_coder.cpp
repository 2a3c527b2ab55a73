#include "codec/range_coder.h"

#include <array>
#include <cmath>
#include <vector>

namespace mm::codec_detail {
namespace {

constexpr std::uint32_t kTop = 1u << 24;
constexpr std::uint32_t kMinP = 48, kMaxP = 65536 - 48;

std::uint32_t bound(std::uint32_t range, const BitModel& m) { return (range >> 16) * m.p; }

// -log2(x / 65536) * 256 for x in [0, 65536], computed once: the encoder adds one per coded bit
// (for reports) and the snapping's cost model one per decision, where a log2 and a rounding per
// bit were a few per cent of a compress run (rocker: 2.3 %). The same values as computing them.
const std::uint32_t* cost_table() {
  static const std::vector<std::uint32_t> table = [] {
    std::vector<std::uint32_t> t(65537, 0xFFFFFFFFu);  // x = 0 never occurs (kMinP)
    for (std::uint32_t x = 1; x <= 65536; ++x)
      t[x] = static_cast<std::uint32_t>(std::lround(-std::log2(x / 65536.0) * 256.0));
    return t;
  }();
  return table.data();
}

std::uint64_t cost_of(std::uint32_t p16) { return cost_table()[p16]; }

}  // namespace

std::uint32_t bit_cost_256(const BitModel& m, int b) {
  return static_cast<std::uint32_t>(cost_of(b ? 65536 - m.p : m.p));
}

// x / rate for x < 2^16 as (x * kInverse[rate]) >> 32 with kInverse[rate] = ceil(2^32 / rate):
// the product overshoots x / rate by less than x / 2^32 < 2^-16, less than the 1 / rate the
// fraction of x / rate always falls short of the next integer, so the quotient is exact (the
// tests check every x and rate). The division it replaces was a fifth of bit()'s time.
constexpr std::array<std::uint64_t, kMaxRate + 1> kInverse = [] {
  std::array<std::uint64_t, kMaxRate + 1> t{};
  for (std::uint64_t r = 1; r <= kMaxRate; ++r) t[r] = ((1ull << 32) + r - 1) / r;
  return t;
}();

std::uint32_t divide_by_rate(std::uint32_t x, int rate) {
  return static_cast<std::uint32_t>((static_cast<std::uint64_t>(x) * kInverse[static_cast<std::size_t>(rate)]) >> 32);
}

void adapt(BitModel& m, int b) {
  const int rate = m.n + 2 < kMaxRate ? m.n + 2 : kMaxRate;
  if (m.n < 0xFFFF) ++m.n;
  std::int32_t p = m.p;
  if (b) p -= static_cast<std::int32_t>(divide_by_rate(static_cast<std::uint32_t>(p), rate));
  else p += static_cast<std::int32_t>(divide_by_rate(static_cast<std::uint32_t>(65536 - p), rate));
  if (p < static_cast<std::int32_t>(kMinP)) p = kMinP;
  if (p > static_cast<std::int32_t>(kMaxP)) p = kMaxP;
  m.p = static_cast<std::uint16_t>(p);
}

void RangeEncoder::shift_low() {
  if (low_ < 0xFF000000ull || low_ >= (1ull << 32)) {
    const std::uint8_t carry = static_cast<std::uint8_t>(low_ >> 32);
    if (!first_) out_.push_back(static_cast<std::uint8_t>(cache_ + carry));
    first_ = false;
    for (; pending_ > 0; --pending_) out_.push_back(static_cast<std::uint8_t>(0xFF + carry));
    cache_ = static_cast<std::uint8_t>(low_ >> 24);
  } else {
    ++pending_;
  }
  low_ = (low_ & 0x00FFFFFFull) << 8;
}

void RangeEncoder::bit(BitModel& m, int b) {
  const std::uint32_t bd = bound(range_, m);
  if (count_cost_) cost_ += cost_of(b ? 65536 - m.p : m.p);
  if (b) {
    low_ += bd;
    range_ -= bd;
  } else {
    range_ = bd;
  }
  adapt(m, b);
  while (range_ < kTop) {
    range_ <<= 8;
    shift_low();
  }
}

void RangeEncoder::bits(std::uint32_t value, int count) {
  if (count_cost_) cost_ += 256ull * static_cast<std::uint64_t>(count);
  for (int i = count - 1; i >= 0; --i) {
    range_ >>= 1;
    if ((value >> i) & 1) low_ += range_;
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
}

std::vector<std::uint8_t> RangeEncoder::finish() {
  // Any value in [low, low + range) decodes the same decisions; take the one with the most
  // trailing zero bits, so that dropping trailing zero bytes removes as much as possible.
  const std::uint64_t hi = low_ + range_ - 1;
  std::uint64_t v = hi;
  for (int k = 32; k >= 0; --k) {
    const std::uint64_t mask = (1ull << k) - 1;
    const std::uint64_t cand = hi & ~mask;
    if (cand >= low_) {
      v = cand;
      break;
    }
  }
  low_ = v;
  for (int i = 0; i < 5; ++i) shift_low();
  while (!out_.empty() && out_.back() == 0) out_.pop_back();
  return std::move(out_);
}

RangeDecoder::RangeDecoder(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {
  for (int i = 0; i < 4; ++i) code_ = (code_ << 8) | next();
}

int RangeDecoder::bit(BitModel& m) {
  const std::uint32_t bd = bound(range_, m);
  int b;
  if (code_ < bd) {
    range_ = bd;
    b = 0;
  } else {
    code_ -= bd;
    range_ -= bd;
    b = 1;
  }
  adapt(m, b);
  while (range_ < kTop) {
    range_ <<= 8;
    code_ = (code_ << 8) | next();
  }
  return b;
}

std::uint32_t RangeDecoder::bits(int count) {
  std::uint32_t v = 0;
  for (int i = 0; i < count; ++i) {
    range_ >>= 1;
    std::uint32_t b = 0;
    if (code_ >= range_) {
      code_ -= range_;
      b = 1;
    }
    v = (v << 1) | b;
    while (range_ < kTop) {
      range_ <<= 8;
      code_ = (code_ << 8) | next();
    }
  }
  return v;
}

}  // namespace mm::codec_detail
