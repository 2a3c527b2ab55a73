#include "watermark/key_stream.h"

#include <sodium.h>

#include <stdexcept>

namespace mm {
namespace {
void init_sodium() {
  if (sodium_init() < 0) throw std::runtime_error("libsodium could not be initialised");
}
}  // namespace

Key generate_key() {
  init_sodium();
  Key key;
  randombytes_buf(key.data(), key.size());
  return key;
}

Nonce generate_nonce() {
  init_sodium();
  Nonce nonce;
  randombytes_buf(nonce.data(), nonce.size());
  return nonce;
}

std::vector<std::uint8_t> key_stream_bits(const Key& key, const Nonce& nonce, std::size_t count) {
  init_sodium();
  std::vector<std::uint8_t> bytes((count + 7) / 8);
  if (!bytes.empty()) crypto_stream_xchacha20(bytes.data(), bytes.size(), nonce.data(), key.data());
  std::vector<std::uint8_t> bits(count);
  for (std::size_t i = 0; i < count; ++i) bits[i] = (bytes[i / 8] >> (i % 8)) & 1u;
  sodium_memzero(bytes.data(), bytes.size());
  return bits;
}

}  // namespace mm
