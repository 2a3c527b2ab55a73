// Lower-case hexadecimal, as every content address, fingerprint and nonce is written.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace mm::support {

std::string to_hex(const std::uint8_t* data, std::size_t size);
std::vector<std::uint8_t> from_hex(const std::string& hex);  // std::invalid_argument if not hex

}  // namespace mm::support
