// The stream's envelope (magic, version, CRC-32) on its own. The codec uses it; tests use the
// checksum to build hostile streams that pass it, so the checks behind it are exercised too.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace mm::codec_detail {

constexpr std::uint8_t kMagic[4] = {'M', 'M', 'C', 'S'};
// Version 3: compact header and a range-coded body (codec/stream_v3.h). Version 4: the same
// with 6 or 7 quantisation bits, which version 3's header cannot hold; written for those bits
// only, so each stream has one way to be written. Versions 1 and 2 (zstd payloads of an earlier
// development format) are not read.
constexpr std::uint8_t kVersion = 4;
constexpr std::uint8_t kOldestVersion = 3;
constexpr std::size_t kChecksumBytes = 4;

constexpr std::size_t kMaxMetadataEntries = 32, kMaxKeyBytes = 64, kMaxValueBytes = 1024;

// Metadata keys: 1..64 bytes of [A-Za-z0-9_.-].
inline bool valid_key(const std::string& k) {
  if (k.empty() || k.size() > kMaxKeyBytes) return false;
  for (char c : k)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
          c == '.' || c == '-'))
      return false;
  return true;
}

// CRC-32 (zlib polynomial) of the bytes.
std::uint32_t checksum(const std::uint8_t* data, std::size_t size);

// Minimum size of a version 3 stream: magic, version, bits, cell grid (4 varints), two counts,
// checksum.
constexpr std::size_t kMinBytesV3 = 6 + 4 + 2 + kChecksumBytes;

// Checks magic, minimum size, size limit, version and checksum.
void check_envelope(const std::uint8_t* data, std::size_t size, const std::string& source);

}  // namespace mm::codec_detail
