// Customer keys and the master key that protects them at rest.
//
// A customer key is 32 random bytes (the watermark key, mm::Key). In the store it exists only
// sealed with XChaCha20-Poly1305 (libsodium) under a 32-byte master key, with a random 24-byte
// nonce and associated data "meshmark-key|<customer id>|<version>", so a sealed key copied onto
// another customer's row or version does not open. The master key never touches the database: it
// comes from a file that only its owner can read (mode 0600 or stricter) or from the environment
// variable MESHMARK_MASTER_KEY (64 hex digits or base64 of 32 bytes).
//
// Secrets never appear in logs, payloads, reports or error messages: SecretKey has no printing,
// and every KeyError message names the file, customer or version, never bytes.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace mm::keys {

constexpr std::size_t kKeyBytes = 32;
constexpr const char* kMasterKeyEnv = "MESHMARK_MASTER_KEY";

struct KeyError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// 32 secret bytes, wiped (sodium_memzero) when destroyed or overwritten. Deliberately no
// operator<<, no to_string: to show a key to a human is a decision made elsewhere, not by accident.
class SecretKey {
 public:
  SecretKey();  // all zero
  SecretKey(const SecretKey& other);
  SecretKey& operator=(const SecretKey& other);
  ~SecretKey();

  static SecretKey random();                                      // randombytes_buf
  static SecretKey from_bytes(const std::uint8_t* data, std::size_t size);  // size must be 32
  static SecretKey parse_text(const std::string& text, const std::string& source);  // hex or base64

  const std::array<std::uint8_t, kKeyBytes>& bytes() const { return bytes_; }  // == mm::Key
  const std::uint8_t* data() const { return bytes_.data(); }
  bool operator==(const SecretKey& o) const;  // constant time
  bool operator!=(const SecretKey& o) const { return !(*this == o); }

 private:
  std::array<std::uint8_t, kKeyBytes> bytes_;
};

// A 32-byte secret from a file (the master key, the evidence signing key's seed): refuses
// (KeyError naming `label`, the path and the mode) unless the file is a regular file without any
// group/other permission bits; content is hex or base64 text.
SecretKey load_secret_key_file(const std::string& path, const std::string& label);
// Creates a new random secret file with mode 0600 (O_EXCL: never overwrites an existing one).
void create_secret_key_file(const std::string& path, const std::string& label);

// Master key from a file: refuses (KeyError naming the path and the mode) unless the file is a
// regular file without any group/other permission bits; content is hex or base64 text.
SecretKey load_master_key_file(const std::string& path);
// Master key from MESHMARK_MASTER_KEY if set (KeyError if set but malformed), else nullopt.
std::optional<SecretKey> master_key_from_env();
// The environment wins over the file, so a deployment can keep the key out of the filesystem.
SecretKey load_master_key(const std::string& file_path);
// Creates a new random master key file with mode 0600 (O_EXCL: never overwrites an existing one;
// KeyError if it exists). Written to a temporary name, fsynced, renamed.
void create_master_key_file(const std::string& path);

// A check value of the master key (BLAKE2b-256 keyed with it over a fixed label): stored with the
// database so a wrong master key is refused at once. It reveals nothing about the key.
std::array<std::uint8_t, 32> master_key_check(const SecretKey& master);

struct SealedKey {
  std::vector<std::uint8_t> nonce;       // 24 bytes
  std::vector<std::uint8_t> ciphertext;  // 32 bytes + 16-byte tag
};
SealedKey seal_customer_key(const SecretKey& master, const SecretKey& key, std::int64_t customer_id,
                            int version);
// KeyError("cannot open key of customer C version V: wrong master key or tampered record").
SecretKey open_customer_key(const SecretKey& master, const SealedKey& sealed,
                            std::int64_t customer_id, int version);

}  // namespace mm::keys
