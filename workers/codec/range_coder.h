// Adaptive binary range coder for stream format version 3 (docs/stream-format.md describes it
// bit for bit). Control polyhedra are streams of a few hundred bytes: zstd's frame overhead and
// its byte-oriented modelling cost more there than they save, while a binary arithmetic coder
// with small adaptive context models codes each decision in a fraction of a bit and has no
// per-stream overhead beyond its final bytes. No Debian package offers such a coder as a library
// (zstd, xz and brotli bundle theirs internally), so this is a small one in the style of LZMA's:
// 32-bit range, carry propagation through a cached byte, 16-bit probabilities.
//
// Differences from LZMA's coder, to save bytes on tiny streams: the leading byte (always 0) is
// not written; the final flush writes the value with the most trailing zero bits inside the
// final interval and then drops trailing zero bytes, and the decoder reads zero bytes past the
// end. Probabilities adapt with rate 1/(n + 2) for a model's n-th decision, down to 1/kMaxRate
// (fast learning on few samples, then stable).
#pragma once
#include <cstdint>
#include <vector>

namespace mm::codec_detail {

// Probability that the next bit is 0, in units of 2^-16, and how often it has been used.
struct BitModel {
  std::uint16_t p = 1u << 15;
  std::uint16_t n = 0;
};

constexpr int kMaxRate = 30;

class RangeEncoder {
 public:
  // `count_cost`: keep cost_256() (reports). Its table lookup per bit was 40 % of bit()'s time,
  // so encoders that only want the bytes leave it off.
  explicit RangeEncoder(bool count_cost = true) : count_cost_(count_cost) {}
  void bit(BitModel& m, int b);
  // `count` (<= 24) bits with probability one half each, most significant first.
  void bits(std::uint32_t value, int count);
  // Flushes and returns the bytes. The encoder must not be used afterwards.
  std::vector<std::uint8_t> finish();
  // Ideal cost so far, in 1/256 bits, of the modelled decisions plus the plain bits (for
  // reports); 0 without count_cost.
  std::uint64_t cost_256() const { return cost_; }

 private:
  void shift_low();
  std::uint64_t low_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint8_t cache_ = 0;
  std::uint64_t pending_ = 0;  // bytes (0xFF) waiting behind the cache for a possible carry
  bool first_ = true;          // the leading byte is always 0 and is not written
  std::vector<std::uint8_t> out_;
  std::uint64_t cost_ = 0;
  bool count_cost_;
};

class RangeDecoder {
 public:
  RangeDecoder(const std::uint8_t* data, std::size_t size);
  int bit(BitModel& m);
  std::uint32_t bits(int count);
  // Bytes read so far, counting the zero bytes read past the end.
  std::size_t consumed() const { return pos_; }
  std::size_t size() const { return size_; }

 private:
  std::uint8_t next() { return pos_ < size_ ? data_[pos_++] : (++pos_, 0); }
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint32_t code_ = 0;
};

// Shared by both sides so the models evolve identically.
void adapt(BitModel& m, int b);
// x / rate for x < 2^16 and 1 <= rate <= kMaxRate, as integer division gives it, by a multiply.
std::uint32_t divide_by_rate(std::uint32_t x, int rate);

// Ideal cost in 1/256 bits of coding b with m, without adapting m (the encoder's rate-distortion
// choices weigh candidate values with it; never affects how a given value is coded).
std::uint32_t bit_cost_256(const BitModel& m, int b);

}  // namespace mm::codec_detail
