// Secret keys and the pseudo-random sequence of paper IV.B, from libsodium's XChaCha20 stream:
// the same (key, nonce) gives the same bits on every platform, and the bits reveal nothing usable
// about the key.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

namespace mm {

using Key = std::array<std::uint8_t, 32>;    // 256-bit customer key
using Nonce = std::array<std::uint8_t, 24>;  // per-copy nonce for the XChaCha20 key stream

// From the operating system's CSPRNG (libsodium randombytes_buf).
Key generate_key();
Nonce generate_nonce();

// The first `count` bits of crypto_stream_xchacha20(key, nonce), each 0 or 1; bit i is bit
// (i mod 8) (least significant first) of stream byte i / 8.
std::vector<std::uint8_t> key_stream_bits(const Key& key, const Nonce& nonce, std::size_t count);

}  // namespace mm
