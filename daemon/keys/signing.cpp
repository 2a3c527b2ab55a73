#include "keys/signing.h"

#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "keys/key_text.h"
#include "support/atomic_file.h"
#include "support/hex.h"
#include "support/sha256.h"

namespace mm::keys {
using detail::ensure_sodium;
using detail::trim;

std::string to_base64(const std::string& bytes) {
  ensure_sodium();
  std::string out(sodium_base64_encoded_len(bytes.size(), sodium_base64_VARIANT_ORIGINAL), '\0');
  sodium_bin2base64(out.data(), out.size(), reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(),
                    sodium_base64_VARIANT_ORIGINAL);
  out.resize(std::strlen(out.c_str()));
  return out;
}

std::string from_base64(const std::string& text, const std::string& source) {
  ensure_sodium();
  std::string out(text.size(), '\0');
  std::size_t len = 0;
  const char* end = nullptr;
  if (sodium_base642bin(reinterpret_cast<unsigned char*>(out.data()), out.size(), text.c_str(), text.size(), nullptr,
                        &len, &end, sodium_base64_VARIANT_ORIGINAL) != 0 ||
      end != text.c_str() + text.size())
    throw KeyError(source + ": not valid base64");
  out.resize(len);
  return out;
}

std::string PublicKey::id() const { return support::sha256_hex(bytes.data(), bytes.size()).substr(0, 16); }

std::string PublicKey::base64() const { return to_base64(std::string(bytes.begin(), bytes.end())); }

PublicKey PublicKey::parse(const std::string& text, const std::string& source) {
  std::string t = trim(text);
  if (t.rfind("ed25519:", 0) == 0) t = t.substr(8);
  PublicKey k;
  std::string raw;
  if (t.size() == 64 && t.find_first_not_of("0123456789abcdefABCDEF") == std::string::npos) {
    const std::vector<std::uint8_t> bytes = support::from_hex(t);
    std::copy(bytes.begin(), bytes.end(), k.bytes.begin());
    return k;
  }
  try {
    raw = from_base64(t, source);
  } catch (const KeyError&) {
    raw.clear();
  }
  if (raw.size() != 32) throw KeyError(source + ": not an Ed25519 public key (expected ed25519:<base64 of 32 bytes>)");
  std::copy(raw.begin(), raw.end(), k.bytes.begin());
  return k;
}

SigningKey::SigningKey(const SecretKey& seed) {
  ensure_sodium();
  crypto_sign_seed_keypair(public_.bytes.data(), secret_.data(), seed.data());
}
SigningKey::SigningKey(const SigningKey& other) : secret_(other.secret_), public_(other.public_) {}
SigningKey::~SigningKey() { sodium_memzero(secret_.data(), secret_.size()); }

std::vector<std::uint8_t> SigningKey::sign(const std::string& message) const {
  std::vector<std::uint8_t> sig(crypto_sign_BYTES);
  crypto_sign_detached(sig.data(), nullptr, reinterpret_cast<const unsigned char*>(message.data()), message.size(),
                       secret_.data());
  return sig;
}

bool signature_valid(const PublicKey& key, const std::string& message, const std::vector<std::uint8_t>& signature) {
  ensure_sodium();
  if (signature.size() != crypto_sign_BYTES) return false;
  return crypto_sign_verify_detached(signature.data(), reinterpret_cast<const unsigned char*>(message.data()),
                                     message.size(), key.bytes.data()) == 0;
}

SigningKey load_signing_key(const std::string& file_path) {
  const char* v = std::getenv(kSigningKeyEnv);
  if (v && *v) return SigningKey(SecretKey::parse_text(v, std::string("environment variable ") + kSigningKeyEnv));
  return SigningKey(load_secret_key_file(file_path, "signing key file"));
}

SigningKey load_or_create_signing_key(const std::string& file_path, const std::string& public_dir) {
  const char* v = std::getenv(kSigningKeyEnv);
  struct stat st {};
  if (!(v && *v) && ::lstat(file_path.c_str(), &st) != 0) create_secret_key_file(file_path, "signing key file");
  SigningKey k = load_signing_key(file_path);
  record_public_key(k.public_key(), public_dir);
  return k;
}

SigningKey rotate_signing_key(const std::string& file_path, const std::string& public_dir) {
  const char* v = std::getenv(kSigningKeyEnv);
  if (v && *v)
    throw KeyError(std::string("the signing key comes from ") + kSigningKeyEnv + "; rotate it there");
  load_or_create_signing_key(file_path, public_dir);  // the old key's public half is recorded
  const std::string next = file_path + ".next";
  std::filesystem::remove(next);
  create_secret_key_file(next, "signing key file");
  if (::rename(next.c_str(), file_path.c_str()) != 0) {
    std::filesystem::remove(next);
    throw KeyError("signing key file " + file_path + ": cannot replace it");
  }
  return load_or_create_signing_key(file_path, public_dir);  // records the new public key
}

void record_public_key(const PublicKey& key, const std::string& public_dir) {
  std::error_code ec;
  std::filesystem::create_directories(public_dir, ec);
  if (ec) throw KeyError("cannot create " + public_dir + ": " + ec.message());
  const std::string path = public_dir + "/" + key.id() + ".pub";
  if (::access(path.c_str(), F_OK) == 0) return;
  support::write_file_atomic(path, key.text() + "\n", 0644);
}

std::vector<PublicKey> recorded_public_keys(const std::string& public_dir) {
  std::vector<PublicKey> keys;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(public_dir, ec)) {
    if (e.path().extension() != ".pub") continue;
    std::ifstream in(e.path());
    std::stringstream ss;
    ss << in.rdbuf();
    keys.push_back(PublicKey::parse(ss.str(), e.path().string()));
  }
  std::sort(keys.begin(), keys.end(), [](const PublicKey& a, const PublicKey& b) { return a.id() < b.id(); });
  return keys;
}

}  // namespace mm::keys
