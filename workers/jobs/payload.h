// The payload hidden in a copy: a random number of `bits` bits that identifies the copy among all
// copies of its asset (chosen unique per asset by the caller), as watermark message bits.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace mm::jobs {

std::vector<bool> payload_to_bits(std::uint64_t payload, int bits);  // least significant first
std::uint64_t bits_to_payload(const std::vector<bool>& bits);
std::string payload_hex(std::uint64_t payload, int bits);  // fixed width, ceil(bits/4) digits
std::uint64_t parse_payload_hex(const std::string& hex);   // std::invalid_argument if malformed

}  // namespace mm::jobs
