// The stream's outer layer (header, payload compression, checksum) on its own. The codec uses
// it; tests use it to build hostile streams whose checksum is valid, so the payload checks
// behind the checksum are exercised too.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace mm::codec_detail {

constexpr std::uint8_t kMagic[4] = {'M', 'M', 'C', 'S'};
// Version 2: plain face indices relative to the count of vertices seen so far,
// parallelogram prediction. Version 1 (still read): plain indices, predictions 0-2.
// Version 3: compact header and a range-coded body (codec/stream_v3.h); written by default.
// Version 4: version 3 with 6 or 7 quantisation bits, which version 3's header cannot hold;
// written instead of version 3 for those bits only.
constexpr std::uint8_t kVersion = 4;
constexpr std::uint8_t kOldestVersion = 1;
constexpr std::uint8_t kFlagZstd = 1;         // payload is one zstd frame (else stored as is)
// Bits 1-2: coordinate prediction (codec/prediction.h: 0 plain, 1 previous vertex, 2 neighbours,
// 3 parallelogram from version 2 on).
constexpr int kPredictionShift = 1;
constexpr std::uint8_t kPredictionMask = 6;
constexpr std::uint8_t kKnownFlags = kFlagZstd | kPredictionMask;
constexpr std::size_t kFixedHeaderBytes = 39;  // magic .. step
constexpr std::size_t kChecksumBytes = 4;
// A real payload (Rice-coded coordinates do not compress) never shrinks this much under zstd;
// a frame that claims more is refused before its output buffer is allocated, so memory stays
// linear in the stream size. The encoder stores payloads that would exceed it.
constexpr std::size_t kMaxExpansion = 64;
constexpr std::size_t kExpansionFloor = 1u << 16;

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

struct Header {
  std::uint8_t version = 2;
  std::uint8_t flags = 0;
  std::uint8_t bits = 12;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  double step = 1.0;
  std::uint32_t vertices = 0, faces = 0, creases = 0, corners = 0, metadata_entries = 0;
  std::uint64_t raw_size = 0;  // payload bytes after decompression
};

struct Parts {
  Header header;
  std::vector<std::uint8_t> raw;  // decompressed payload
};

// CRC-32 (zlib polynomial) of the bytes.
std::uint32_t checksum(const std::uint8_t* data, std::size_t size);

// Builds a stream from a header and a raw payload; header.raw_size and the zstd flag are set
// here (zstd_level <= 0 stores the payload uncompressed). No validation of the contents.
std::vector<std::uint8_t> join(Header header, const std::vector<std::uint8_t>& raw, int zstd_level);

// Minimum size of a version 3 stream: magic, version, bits, cell grid (4 varints), two counts,
// checksum.
constexpr std::size_t kMinBytesV3 = 6 + 4 + 2 + kChecksumBytes;

// Checks magic, minimum size, size limit, version and checksum (all versions).
void check_envelope(const std::uint8_t* data, std::size_t size, const std::string& source);

// Versions 1 and 2: checks magic, version, checksum, flags, quantisation bits, transform, counts and their
// consistency with the payload size, then decompresses. Throws InputError(source, reason).
Parts split(const std::uint8_t* data, std::size_t size, const std::string& source);

}  // namespace mm::codec_detail
