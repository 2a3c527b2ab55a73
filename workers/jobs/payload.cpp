#include "jobs/payload.h"

#include <stdexcept>

namespace mm::jobs {

std::vector<bool> payload_to_bits(std::uint64_t payload, int bits) {
  if (bits < 1 || bits > 64) throw std::invalid_argument("payload width must be 1..64 bits");
  std::vector<bool> out(static_cast<std::size_t>(bits));
  for (int i = 0; i < bits; ++i) out[static_cast<std::size_t>(i)] = (payload >> i) & 1u;
  return out;
}

std::uint64_t bits_to_payload(const std::vector<bool>& bits) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bits.size() && i < 64; ++i)
    if (bits[i]) v |= std::uint64_t(1) << i;
  return v;
}

std::string payload_hex(std::uint64_t payload, int bits) {
  static const char* digits = "0123456789abcdef";
  int n = (bits + 3) / 4;
  std::string s(static_cast<std::size_t>(n), '0');
  for (int i = 0; i < n; ++i) s[static_cast<std::size_t>(n - 1 - i)] = digits[(payload >> (4 * i)) & 0xf];
  return s;
}

std::uint64_t parse_payload_hex(const std::string& hex) {
  if (hex.empty() || hex.size() > 16) throw std::invalid_argument("payload hex must be 1..16 digits");
  std::uint64_t v = 0;
  for (char c : hex) {
    int d;
    if (c >= '0' && c <= '9') d = c - '0';
    else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    else throw std::invalid_argument("payload hex has a non-hex digit");
    v = (v << 4) | static_cast<std::uint64_t>(d);
  }
  return v;
}

}  // namespace mm::jobs
