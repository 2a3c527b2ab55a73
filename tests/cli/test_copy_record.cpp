// The copy record, message encoding, nonce derivation and key files, called directly.
#include <gtest/gtest.h>

#include <fstream>

#include "cli/copy_record.h"
#include "cli/key_file.h"
#include "cli_test_util.h"
#include "meshio/mesh.h"

using namespace mm;
using namespace mm::cli;

namespace {

CopyRecord sample_record() {
  CopyRecord r;
  r.meshmark_version = "0.1.0";
  r.original_file = "part.off";
  r.original_sha256 = std::string(64, '1');
  r.original_kind = "mesh";
  r.control_vertices = 66;
  r.control_faces = 128;
  r.basis_fingerprint = std::string(64, '2');
  r.params = {Method::Multiplicative, 0.02, 0.1};
  r.message = "bob";
  r.message_bits = 24;
  for (int i = 0; i < 24; ++i) r.nonce[i] = static_cast<std::uint8_t>(i * 7);
  r.key_fingerprint = "mmkey1:" + std::string(64, '3');
  r.output_file = "bob.mmc";
  r.output_kind = "stream";
  r.output_sha256 = std::string(64, '4');
  r.output_quant_bits = 14;
  r.output_check_correlation = 0.98;
  return r;
}

}  // namespace

TEST(Message, BytesMostSignificantBitFirstAndBack) {
  const auto bits = message_to_bits("a\xc3\xa9");  // 'a' = 0x61, then U+00E9 in UTF-8
  ASSERT_EQ(bits.size(), 24u);
  EXPECT_EQ(bits_to_string(bits), "011000011100001110101001");
  EXPECT_EQ(bits_to_bytes(bits), "a\xc3\xa9");
}

TEST(Message, Utf8Validation) {
  EXPECT_TRUE(valid_utf8("copy:alice"));
  EXPECT_TRUE(valid_utf8("gr\xc3\xbc\xc3\x9f"));
  EXPECT_FALSE(valid_utf8("\xff"));
  EXPECT_FALSE(valid_utf8("\xc3"));          // truncated sequence
  EXPECT_FALSE(valid_utf8("\xc0\xaf"));      // overlong '/'
  EXPECT_FALSE(valid_utf8("\xed\xa0\x80"));  // surrogate
}

TEST(Nonce, DeterministicAndSeparatedByKeyMessageAndParameters) {
  Key k1{}, k2{};
  k2[0] = 1;
  const std::string sha(64, 'a');
  const EmbedParams p{};
  const Nonce n = derive_nonce(k1, sha, p, "alice");
  EXPECT_EQ(n, derive_nonce(k1, sha, p, "alice"));
  EXPECT_NE(n, derive_nonce(k2, sha, p, "alice"));
  EXPECT_NE(n, derive_nonce(k1, sha, p, "alicf"));
  EXPECT_NE(n, derive_nonce(k1, std::string(64, 'b'), p, "alice"));
  EXPECT_NE(n, derive_nonce(k1, sha, {Method::Additive, 0.02, 0.05}, "alice"));
  EXPECT_NE(n, derive_nonce(k1, sha, {Method::Multiplicative, 0.01, 0.05}, "alice"));
}

TEST(Record, JsonRoundTripIsExactAndHoldsNoKey) {
  const CopyRecord r = sample_record();
  const std::string text = record_to_json(r);
  const CopyRecord back = record_from_json(text, "rec.json");
  EXPECT_EQ(record_to_json(back), text);
  EXPECT_EQ(back.params.method, Method::Multiplicative);
  EXPECT_EQ(back.params.strength, 0.02);
  EXPECT_EQ(back.nonce, r.nonce);
  EXPECT_EQ(back.output_quant_bits, 14);
  EXPECT_EQ(back.message, "bob");
}

TEST(Record, MalformedRecordsNameTheSource) {
  const std::string good = record_to_json(sample_record());
  auto expect_bad = [](const std::string& text, const std::string& reason_part) {
    try {
      record_from_json(text, "rec.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.source(), "rec.json");
      EXPECT_NE(e.reason().find(reason_part), std::string::npos) << e.reason();
    }
  };
  expect_bad("", "malformed JSON");
  expect_bad(good.substr(0, good.size() / 2), "malformed JSON");
  expect_bad("{\"format\": \"something else\"}", "format");
  auto replace = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  expect_bad(replace("\"format_version\": 1", "\"format_version\": 2"), "format_version 2");
  expect_bad(replace("\"message_bits\": 24", "\"message_bits\": 25"), "message_bits");
  expect_bad(replace("\"method\": 1", "\"method\": 4"), "method");
  expect_bad(replace("\"strength\": 0.02", "\"strength\": 1.5"), "strength");
  expect_bad(replace("\"nonce\": \"00", "\"nonce\": \"zz"), "nonce");
  expect_bad(replace("\"nonce\": \"00", "\"nonce\": \""), "nonce");
  expect_bad(replace("\"key_fingerprint\"", "\"key_id\""), "missing or mistyped");
}

TEST(KeyFile, ReadsKeygenFormatAndRejectsOthers) {
  test::Scratch s;
  const std::string path = test::write_key(s, "k.key", 'c');
  const Key k = read_key_file(path);
  for (auto b : k) EXPECT_EQ(b, 0xcc);
  EXPECT_EQ(key_file_text(k), std::string(64, 'c') + "\n");
  EXPECT_FALSE(key_file_exposed(path));
  std::filesystem::permissions(path, std::filesystem::perms::group_read, std::filesystem::perm_options::add);
  EXPECT_TRUE(key_file_exposed(path));
  EXPECT_EQ(key_fingerprint(k).substr(0, 7), "mmkey1:");
  EXPECT_EQ(key_fingerprint(k).find(std::string(64, 'c')), std::string::npos);
  for (const std::string& bad : {std::string(63, 'c'), std::string(66, 'c'), std::string(62, 'c') + "zz", std::string()}) {
    std::ofstream(s / "bad.key") << bad;
    try {
      read_key_file(s / "bad.key");
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const InputError& e) {
      EXPECT_EQ(e.source(), s / "bad.key");
      EXPECT_NE(e.reason().find("64 hexadecimal digits"), std::string::npos);
    }
  }
}
