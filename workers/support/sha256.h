// SHA-256 content addresses (libsodium), in lower-case hex.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace mm::support {

// Incremental: update() with each piece, then hex() once.
class Sha256 {
 public:
  Sha256();
  void update(const void* data, std::size_t size);
  std::string hex();

 private:
  alignas(16) unsigned char state_[128];  // crypto_hash_sha256_state
};

std::string sha256_hex(const void* data, std::size_t size);
std::string sha256_hex(const std::vector<std::uint8_t>& bytes);
// Reads the file in pieces; std::system_error (errno, naming the path) if it cannot be read.
std::string sha256_file_hex(const std::string& path);

}  // namespace mm::support
