// The installation's evidence signing key: Ed25519 (libsodium), kept like the master key.
//
// The 32-byte seed comes from MESHMARK_SIGNING_KEY (hex or base64) or from <home>/signing.key, a
// file its owner alone can read; it never touches the database, logs or packages. Packages carry
// the public key and its id, and every public key the home ever signed with is kept under
// <home>/signing-keys/<id>.pub, so rotating the key leaves older packages verifiable.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "keys/keys.h"

namespace mm::keys {

constexpr const char* kSigningKeyEnv = "MESHMARK_SIGNING_KEY";

struct PublicKey {
  std::array<std::uint8_t, 32> bytes{};
  // First 16 hex digits of the SHA-256 of the key bytes: names the key in packages.
  std::string id() const;
  std::string base64() const;
  // "ed25519:<base64>" or plain base64 / 64 hex digits; KeyError naming `source` otherwise.
  static PublicKey parse(const std::string& text, const std::string& source);
  std::string text() const { return "ed25519:" + base64(); }  // what `evidence pubkey` prints
  bool operator==(const PublicKey& o) const { return bytes == o.bytes; }
};

class SigningKey {
 public:
  explicit SigningKey(const SecretKey& seed);
  SigningKey(const SigningKey& other);
  SigningKey& operator=(const SigningKey&) = delete;
  ~SigningKey();
  const PublicKey& public_key() const { return public_; }
  std::vector<std::uint8_t> sign(const std::string& message) const;  // 64-byte detached signature

 private:
  std::array<std::uint8_t, 64> secret_{};
  PublicKey public_;
};

bool signature_valid(const PublicKey& key, const std::string& message, const std::vector<std::uint8_t>& signature);

// The environment wins over the file. KeyError when neither holds a usable key.
SigningKey load_signing_key(const std::string& file_path);
// Loads the key, creating the file (0600) first when neither it nor the environment variable
// exists, and records its public key under public_dir.
SigningKey load_or_create_signing_key(const std::string& file_path, const std::string& public_dir);
// Replaces the key file with a new random seed (written beside it, renamed over it) after
// recording the old public key, and records the new one; returns the new key. KeyError when the
// key comes from the environment (rotate it there) or the file cannot be replaced.
SigningKey rotate_signing_key(const std::string& file_path, const std::string& public_dir);
// Every public key recorded under public_dir (files <id>.pub), sorted by id.
std::vector<PublicKey> recorded_public_keys(const std::string& public_dir);
void record_public_key(const PublicKey& key, const std::string& public_dir);

// Standard base64 (with padding) of bytes, and back (KeyError naming `source` when malformed).
std::string to_base64(const std::string& bytes);
std::string from_base64(const std::string& text, const std::string& source);

}  // namespace mm::keys
