#include "cli/copy_record.h"

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli/file_util.h"
#include "jobs/copy_identity.h"

namespace mm::cli {

std::vector<bool> message_to_bits(const std::string& text) {
  std::vector<bool> bits;
  bits.reserve(8 * text.size());
  for (unsigned char c : text)
    for (int k = 7; k >= 0; --k) bits.push_back((c >> k) & 1);
  return bits;
}

std::string bits_to_bytes(const std::vector<bool>& bits) {
  std::string out(bits.size() / 8, '\0');
  for (std::size_t i = 0; i < out.size(); ++i) {
    unsigned v = 0;
    for (int k = 0; k < 8; ++k) v = (v << 1) | (bits[8 * i + k] ? 1u : 0u);
    out[i] = static_cast<char>(v);
  }
  return out;
}

std::string bits_to_string(const std::vector<bool>& bits) {
  std::string s;
  s.reserve(bits.size());
  for (bool b : bits) s.push_back(b ? '1' : '0');
  return s;
}

bool valid_utf8(const std::string& s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    int len = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (len == 0 || i + len > s.size()) return false;
    std::uint32_t cp = len == 1 ? c : c & (0x7F >> len);
    for (int k = 1; k < len; ++k) {
      const unsigned char d = static_cast<unsigned char>(s[i + k]);
      if ((d >> 6) != 0x2) return false;
      cp = (cp << 6) | (d & 0x3F);
    }
    // Overlong forms, surrogates and values past U+10FFFF are not UTF-8.
    if ((len == 2 && cp < 0x80) || (len == 3 && cp < 0x800) || (len == 4 && cp < 0x10000) ||
        (cp >= 0xD800 && cp <= 0xDFFF) || cp > 0x10FFFF)
      return false;
    i += len;
  }
  return true;
}

namespace {

// Shortest decimal that reads back as the same double: records and nonces must not depend on
// how a parameter was spelt on the command line, only on its value.
std::string exact(double x) {
  char buf[32];
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, x);
    if (std::strtod(buf, nullptr) == x) break;
  }
  return buf;
}

}  // namespace

Nonce derive_nonce(const Key& key, const std::string& original_sha256, const EmbedParams& params,
                   const std::string& message) {
  return jobs::derive_copy_identity({"embed", original_sha256, std::to_string(static_cast<int>(params.method)),
                                     exact(params.strength), exact(params.threshold),
                                     to_hex(reinterpret_cast<const std::uint8_t*>(message.data()), message.size())},
                                    &key)
      .nonce;
}

std::string record_to_json(const CopyRecord& r) {
  using nlohmann::ordered_json;
  ordered_json output{{"file", r.output_file}, {"kind", r.output_kind}, {"sha256", r.output_sha256}};
  if (r.output_kind == "subdivided") output["level"] = r.output_level;
  if (r.output_kind == "stream") {
    output["quant_bits"] = r.output_quant_bits;
    output["check_correlation"] = r.output_check_correlation;
  }
  ordered_json j{
      {"format", "meshmark-copy-record"},
      {"format_version", r.format_version},
      {"meshmark_version", r.meshmark_version},
      {"original",
       {{"file", r.original_file}, {"sha256", r.original_sha256}, {"kind", r.original_kind}}},
      {"control",
       {{"vertices", r.control_vertices},
        {"faces", r.control_faces},
        {"basis_fingerprint", r.basis_fingerprint}}},
      {"watermark",
       {{"method", static_cast<int>(r.params.method)},
        {"strength", r.params.strength},
        {"threshold", r.params.threshold},
        {"message", r.message},
        {"message_bits", r.message_bits},
        {"nonce", to_hex(r.nonce.data(), r.nonce.size())},
        {"key_fingerprint", r.key_fingerprint}}},
      {"output", output}};
  return j.dump(2) + "\n";
}

CopyRecord record_from_json(const std::string& text, const std::string& source) {
  using nlohmann::json;
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(source, std::string("not a copy record (malformed JSON: ") + e.what() + ")");
  }
  auto fail = [&](const std::string& why) -> void { throw InputError(source, "not a valid copy record: " + why); };
  // A "format" of another type is refused like a wrong one (json::value would throw type_error).
  if (!j.is_object() || !j.contains("format") || !j["format"].is_string() ||
      j["format"].get<std::string>() != "meshmark-copy-record")
    fail("\"format\" is not \"meshmark-copy-record\"");
  CopyRecord r;
  try {
    r.format_version = j.at("format_version").get<int>();
    if (r.format_version != kRecordFormatVersion)
      fail("format_version " + std::to_string(r.format_version) + " is not supported (this build reads " +
           std::to_string(kRecordFormatVersion) + ")");
    r.meshmark_version = j.at("meshmark_version").get<std::string>();
    const json& o = j.at("original");
    r.original_file = o.at("file").get<std::string>();
    r.original_sha256 = o.at("sha256").get<std::string>();
    r.original_kind = o.at("kind").get<std::string>();
    const json& c = j.at("control");
    r.control_vertices = c.at("vertices").get<int>();
    r.control_faces = c.at("faces").get<int>();
    r.basis_fingerprint = c.at("basis_fingerprint").get<std::string>();
    const json& w = j.at("watermark");
    const int method = w.at("method").get<int>();
    if (method < 1 || method > 3) fail("watermark.method must be 1, 2 or 3");
    r.params.method = static_cast<Method>(method);
    r.params.strength = w.at("strength").get<double>();
    r.params.threshold = w.at("threshold").get<double>();
    if (!(r.params.strength > 0 && r.params.strength < 1)) fail("watermark.strength must be in (0, 1)");
    if (!(std::isfinite(r.params.threshold) && r.params.threshold >= 0)) fail("watermark.threshold must be >= 0");
    r.message = w.at("message").get<std::string>();
    r.message_bits = w.at("message_bits").get<int>();
    if (r.message.empty() || static_cast<int>(r.message.size()) > kMaxMessageBytes ||
        r.message_bits != 8 * static_cast<int>(r.message.size()))
      fail("watermark.message_bits does not match a 1.." + std::to_string(kMaxMessageBytes) + "-byte message");
    std::vector<std::uint8_t> nonce;
    try {
      nonce = from_hex(w.at("nonce").get<std::string>());
    } catch (const std::invalid_argument&) {
      fail("watermark.nonce is not hexadecimal");
    }
    if (nonce.size() != r.nonce.size()) fail("watermark.nonce must be 24 bytes");
    std::memcpy(r.nonce.data(), nonce.data(), r.nonce.size());
    r.key_fingerprint = w.at("key_fingerprint").get<std::string>();
    const json& out = j.at("output");
    r.output_file = out.at("file").get<std::string>();
    r.output_kind = out.at("kind").get<std::string>();
    r.output_sha256 = out.at("sha256").get<std::string>();
    if (r.output_kind == "subdivided") r.output_level = out.at("level").get<int>();
    if (r.output_kind == "stream") {
      r.output_quant_bits = out.at("quant_bits").get<int>();
      r.output_check_correlation = out.at("check_correlation").get<double>();
    }
  } catch (const json::exception& e) {
    fail(std::string("missing or mistyped field (") + e.what() + ")");
  }
  if (r.original_sha256.size() != 64 || r.basis_fingerprint.size() != 64)
    fail("original.sha256 and control.basis_fingerprint must be 64 hex digits");
  if (r.control_vertices <= 0) fail("control.vertices must be positive");
  return r;
}

}  // namespace mm::cli
