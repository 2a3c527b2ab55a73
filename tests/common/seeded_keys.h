// Seeded customer keys and nonces for tests: the same seed, the same bytes.
#pragma once
#include <cstdint>
#include <random>

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

}  // namespace mm::test
