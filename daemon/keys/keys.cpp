#include "keys/keys.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include "keys/key_text.h"
#include "support/atomic_file.h"

namespace mm::keys {
namespace {

using detail::ensure_sodium;
using detail::trim;

std::string associated_data(std::int64_t customer_id, int version) {
  return "meshmark-key|" + std::to_string(customer_id) + "|" + std::to_string(version);
}

std::string errno_text() { return std::strerror(errno); }

}  // namespace

SecretKey::SecretKey() { bytes_.fill(0); }
SecretKey::SecretKey(const SecretKey& other) : bytes_(other.bytes_) {}
SecretKey& SecretKey::operator=(const SecretKey& other) {
  if (this != &other) bytes_ = other.bytes_;
  return *this;
}
SecretKey::~SecretKey() { sodium_memzero(bytes_.data(), bytes_.size()); }

SecretKey SecretKey::random() {
  ensure_sodium();
  SecretKey k;
  randombytes_buf(k.bytes_.data(), k.bytes_.size());
  return k;
}

SecretKey SecretKey::from_bytes(const std::uint8_t* data, std::size_t size) {
  if (size != kKeyBytes)
    throw KeyError("a key must be " + std::to_string(kKeyBytes) + " bytes, got " + std::to_string(size));
  SecretKey k;
  std::memcpy(k.bytes_.data(), data, size);
  return k;
}

SecretKey SecretKey::parse_text(const std::string& text, const std::string& source) {
  ensure_sodium();
  std::string t = trim(text);
  SecretKey k;
  std::size_t len = 0;
  const char* end = nullptr;
  // Hex first (exactly 64 digits), then the base64 variants. The message never quotes the text.
  if (t.size() == 2 * kKeyBytes &&
      sodium_hex2bin(k.bytes_.data(), k.bytes_.size(), t.c_str(), t.size(), nullptr, &len, &end) == 0 &&
      len == kKeyBytes && end == t.c_str() + t.size())
    return k;
  for (int variant : {sodium_base64_VARIANT_ORIGINAL, sodium_base64_VARIANT_ORIGINAL_NO_PADDING,
                      sodium_base64_VARIANT_URLSAFE, sodium_base64_VARIANT_URLSAFE_NO_PADDING}) {
    std::uint8_t buf[kKeyBytes + 8];
    if (sodium_base642bin(buf, sizeof buf, t.c_str(), t.size(), nullptr, &len, &end, variant) == 0 &&
        len == kKeyBytes && end == t.c_str() + t.size()) {
      std::memcpy(k.bytes_.data(), buf, kKeyBytes);
      sodium_memzero(buf, sizeof buf);
      return k;
    }
    sodium_memzero(buf, sizeof buf);
  }
  sodium_memzero(t.data(), t.size());
  throw KeyError(source + ": not a 256-bit key (expected 64 hex digits or base64 of 32 bytes)");
}

bool SecretKey::operator==(const SecretKey& o) const {
  return sodium_memcmp(bytes_.data(), o.bytes_.data(), kKeyBytes) == 0;
}

SecretKey load_secret_key_file(const std::string& path, const std::string& label) {
  int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) throw KeyError(label + " " + path + ": cannot open: " + errno_text());
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    throw KeyError(label + " " + path + ": cannot stat: " + errno_text());
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw KeyError(label + " " + path + ": not a regular file");
  }
  if ((st.st_mode & 077) != 0) {
    ::close(fd);
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw KeyError(label + " " + path + " has mode " + mode +
                   "; refusing to use it: it must be readable by its owner only (chmod 600 " + path + ")");
  }
  if (st.st_size > 4096) {
    ::close(fd);
    throw KeyError(label + " " + path + ": too large to be a key");
  }
  std::string text(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t got = 0;
  while (got < text.size()) {
    ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  text.resize(got);
  try {
    SecretKey k = SecretKey::parse_text(text, label + " " + path);
    sodium_memzero(text.data(), text.size());
    return k;
  } catch (...) {
    sodium_memzero(text.data(), text.size());
    throw;
  }
}

std::optional<SecretKey> master_key_from_env() {
  const char* v = std::getenv(kMasterKeyEnv);
  if (!v || !*v) return std::nullopt;
  return SecretKey::parse_text(v, std::string("environment variable ") + kMasterKeyEnv);
}

SecretKey load_master_key_file(const std::string& path) { return load_secret_key_file(path, "master key file"); }
void create_master_key_file(const std::string& path) { create_secret_key_file(path, "master key file"); }

SecretKey load_master_key(const std::string& file_path) {
  if (auto k = master_key_from_env()) return *k;
  return load_master_key_file(file_path);
}

void create_secret_key_file(const std::string& path, const std::string& label) {
  ensure_sodium();
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0)
    throw KeyError(label + " " + path + " already exists; refusing to overwrite it");
  SecretKey k = SecretKey::random();
  char hex[2 * kKeyBytes + 1];
  sodium_bin2hex(hex, sizeof hex, k.data(), kKeyBytes);
  std::string body = std::string(hex) + "\n";
  sodium_memzero(hex, sizeof hex);
  bool written = false;
  std::string why;
  try {
    // Exclusive: never overwrite a key someone else made a moment earlier.
    written = support::write_file_exclusive(path, body, 0600);
    if (!written) why = "it appeared meanwhile";
  } catch (const std::system_error& e) {
    why = e.what();
  }
  sodium_memzero(body.data(), body.size());
  if (!written) throw KeyError(label + " " + path + ": cannot write: " + why);
}

std::array<std::uint8_t, 32> master_key_check(const SecretKey& master) {
  ensure_sodium();
  static const char label[] = "meshmark master key check v1";
  std::array<std::uint8_t, 32> out{};
  crypto_generichash(out.data(), out.size(), reinterpret_cast<const unsigned char*>(label), sizeof label - 1,
                     master.data(), kKeyBytes);
  return out;
}

SealedKey seal_customer_key(const SecretKey& master, const SecretKey& key, std::int64_t customer_id,
                            int version) {
  ensure_sodium();
  SealedKey s;
  s.nonce.resize(crypto_aead_xchacha20poly1305_ietf_NPUBBYTES);
  randombytes_buf(s.nonce.data(), s.nonce.size());
  s.ciphertext.resize(kKeyBytes + crypto_aead_xchacha20poly1305_ietf_ABYTES);
  std::string ad = associated_data(customer_id, version);
  unsigned long long clen = 0;
  crypto_aead_xchacha20poly1305_ietf_encrypt(
      s.ciphertext.data(), &clen, key.data(), kKeyBytes,
      reinterpret_cast<const unsigned char*>(ad.data()), ad.size(), nullptr, s.nonce.data(), master.data());
  s.ciphertext.resize(clen);
  return s;
}

SecretKey open_customer_key(const SecretKey& master, const SealedKey& sealed,
                            std::int64_t customer_id, int version) {
  ensure_sodium();
  std::string what = "cannot open key of customer " + std::to_string(customer_id) + " version " +
                     std::to_string(version);
  if (sealed.nonce.size() != crypto_aead_xchacha20poly1305_ietf_NPUBBYTES ||
      sealed.ciphertext.size() != kKeyBytes + crypto_aead_xchacha20poly1305_ietf_ABYTES)
    throw KeyError(what + ": malformed sealed key record");
  std::string ad = associated_data(customer_id, version);
  std::uint8_t plain[kKeyBytes];
  unsigned long long plen = 0;
  if (crypto_aead_xchacha20poly1305_ietf_decrypt(
          plain, &plen, nullptr, sealed.ciphertext.data(), sealed.ciphertext.size(),
          reinterpret_cast<const unsigned char*>(ad.data()), ad.size(), sealed.nonce.data(),
          master.data()) != 0 ||
      plen != kKeyBytes) {
    sodium_memzero(plain, sizeof plain);
    throw KeyError(what + ": wrong master key or tampered record");
  }
  SecretKey k = SecretKey::from_bytes(plain, kKeyBytes);
  sodium_memzero(plain, sizeof plain);
  return k;
}

}  // namespace mm::keys
