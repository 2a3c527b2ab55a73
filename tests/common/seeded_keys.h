// Seeded customer keys, nonces and messages for tests: the same seed, the same bytes.
#pragma once
#include <cstdint>
#include <random>
#include <vector>

#include "watermark/key_stream.h"

namespace mm::test {

inline Key key_from(int seed) {
  Key k{};
  std::mt19937 g(static_cast<unsigned>(seed));
  for (auto& b : k) b = static_cast<std::uint8_t>(g());
  return k;
}

inline Nonce nonce_from(int seed) {
  Nonce n{};
  std::mt19937 g(static_cast<unsigned>(seed) * 7919u);
  for (auto& b : n) b = static_cast<std::uint8_t>(g());
  return n;
}

// The watermark tests' keys and nonces (64-bit seeds, the generator's high bytes).
inline Key seeded_key(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Key k{};
  for (auto& b : k) b = static_cast<std::uint8_t>(rng() >> 56);
  return k;
}

inline Nonce seeded_nonce(std::uint64_t seed) {
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ull);
  Nonce n{};
  for (auto& b : n) b = static_cast<std::uint8_t>(rng() >> 56);
  return n;
}

// A seeded message of `bits` bits.
inline std::vector<bool> seeded_message(int bits, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<bool> m(static_cast<std::size_t>(bits));
  for (int i = 0; i < bits; ++i) m[static_cast<std::size_t>(i)] = (rng() >> 63) != 0;
  return m;
}

}  // namespace mm::test
