// The copy record `meshmark embed` writes beside each watermarked file (OUT.mmrec.json): what
// non-blind extraction needs besides the original and the key, and the evidence of what was
// issued. It never holds the key, only its fingerprint (key_file.h). docs/cli.md lists the fields.
#pragma once
#include <string>
#include <vector>

#include "watermark/watermark.h"

namespace mm::cli {

constexpr int kRecordFormatVersion = 1;
constexpr int kMaxMessageBytes = 32;  // the message: 1..32 bytes of UTF-8 text, 8..256 bits

// Message text <-> watermark bits: UTF-8 bytes in order, each byte most significant bit first,
// so the bit string reads as the bytes in binary.
std::vector<bool> message_to_bits(const std::string& text);
std::string bits_to_bytes(const std::vector<bool>& bits);  // trailing partial byte dropped
std::string bits_to_string(const std::vector<bool>& bits);  // "0110..."
bool valid_utf8(const std::string& s);

// The per-copy nonce: jobs::derive_copy_identity keyed by the customer key over the original's
// hash, the parameters and the message. Same command, same nonce (byte-identical outputs); another
// customer, message or parameter set gets an unrelated key stream; without the key the nonce
// tells nothing.
Nonce derive_nonce(const Key& key, const std::string& original_sha256, const EmbedParams& params,
                   const std::string& message);

struct CopyRecord {
  int format_version = kRecordFormatVersion;
  std::string meshmark_version;
  // The original the mark was embedded in.
  std::string original_file;    // as given on the command line (informative)
  std::string original_sha256;
  std::string original_kind;    // "mesh" or "stream"
  int control_vertices = 0, control_faces = 0;
  std::string basis_fingerprint;  // spectral_basis.h basis_fingerprint of the normalised control
  // The mark.
  EmbedParams params;
  std::string message;  // UTF-8 text; message_bits = 8 x its bytes
  int message_bits = 0;
  Nonce nonce{};
  std::string key_fingerprint;
  // What was written.
  std::string output_file;      // as given (informative)
  std::string output_kind;      // "polyhedron", "stream" or "subdivided"
  std::string output_sha256;
  int output_level = 0;         // subdivided only
  int output_quant_bits = 0;    // stream only
  double output_check_correlation = 1;  // stream only: correlation measured on the quantised copy
};

std::string record_to_json(const CopyRecord& r);  // pretty, deterministic, ends with "\n"
// Throws InputError(source, reason) for malformed JSON, a missing or mistyped field, an unknown
// format version, or values out of range.
CopyRecord record_from_json(const std::string& text, const std::string& source);

}  // namespace mm::cli
