// The evidence signing key: Ed25519 from a 0600 seed file or the environment, public keys kept for
// verification after rotation, signatures that any changed byte breaks.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <fstream>

#include "keys/signing.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;

TEST(Signing, SeedFileIsOwnerOnlyAndPublicKeysAreRecorded) {
  TempDir dir;
  const std::string key = dir / "signing.key", pubs = dir / "signing-keys";
  ::unsetenv(keys::kSigningKeyEnv);
  const keys::SigningKey k = keys::load_or_create_signing_key(key, pubs);
  struct stat st {};
  ASSERT_EQ(::stat(key.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // Loading again gives the same key; the public key was recorded once.
  EXPECT_EQ(keys::load_or_create_signing_key(key, pubs).public_key(), k.public_key());
  const auto recorded = keys::recorded_public_keys(pubs);
  ASSERT_EQ(recorded.size(), 1u);
  EXPECT_EQ(recorded[0], k.public_key());
  EXPECT_EQ(recorded[0].id().size(), 16u);
  ::chmod(key.c_str(), 0644);
  try {
    keys::load_signing_key(key);
    FAIL() << "accepted a signing key readable by others";
  } catch (const keys::KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("signing key file " + key), std::string::npos) << e.what();
  }
}

TEST(Signing, SignaturesBreakOnAnyChangedByteOrOtherKey) {
  const keys::SigningKey a(keys::SecretKey::from_bytes(std::vector<std::uint8_t>(32, 7).data(), 32));
  const keys::SigningKey b(keys::SecretKey::from_bytes(std::vector<std::uint8_t>(32, 8).data(), 32));
  const std::string msg = "DSSEv1 28 application/vnd.in-toto+json 5 hello";
  const auto sig = a.sign(msg);
  EXPECT_EQ(sig.size(), 64u);
  EXPECT_TRUE(keys::signature_valid(a.public_key(), msg, sig));
  EXPECT_FALSE(keys::signature_valid(b.public_key(), msg, sig));
  for (std::size_t i = 0; i < msg.size(); ++i) {
    std::string m = msg;
    m[i] ^= 1;
    EXPECT_FALSE(keys::signature_valid(a.public_key(), m, sig)) << "byte " << i;
  }
  auto bad = sig;
  bad[10] ^= 0x40;
  EXPECT_FALSE(keys::signature_valid(a.public_key(), msg, bad));
  // Deterministic (Ed25519): the same key and message give the same signature.
  EXPECT_EQ(a.sign(msg), sig);
}

TEST(Signing, PublicKeyTextRoundTripsAndRejectsGarbage) {
  const keys::SigningKey a(keys::SecretKey::from_bytes(std::vector<std::uint8_t>(32, 9).data(), 32));
  const std::string text = a.public_key().text();
  EXPECT_EQ(text.rfind("ed25519:", 0), 0u);
  EXPECT_EQ(keys::PublicKey::parse(text + "\n", "t"), a.public_key());
  EXPECT_EQ(keys::PublicKey::parse(a.public_key().base64(), "t"), a.public_key());
  EXPECT_THROW(keys::PublicKey::parse("ed25519:AAAA", "pub.txt"), keys::KeyError);
  EXPECT_THROW(keys::PublicKey::parse("not a key", "pub.txt"), keys::KeyError);
  EXPECT_EQ(keys::from_base64(keys::to_base64(std::string("\0\1\2xyz", 6)), "t"), std::string("\0\1\2xyz", 6));
}

TEST(Signing, EnvironmentWinsOverTheFile) {
  TempDir dir;
  const std::string key = dir / "signing.key";
  const keys::SigningKey from_file = keys::load_or_create_signing_key(key, dir / "pubs");
  ::setenv(keys::kSigningKeyEnv, std::string(64, 'a').c_str(), 1);
  const keys::SigningKey from_env = keys::load_signing_key(key);
  ::unsetenv(keys::kSigningKeyEnv);
  EXPECT_FALSE(from_env.public_key() == from_file.public_key());
  EXPECT_EQ(keys::load_signing_key(key).public_key(), from_file.public_key());
}
