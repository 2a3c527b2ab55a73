#include "cli/key_file.h"

#include <sodium.h>
#include <sys/stat.h>

#include <cctype>
#include <cstring>

#include "cli/file_util.h"
#include "meshio/mesh.h"

namespace mm::cli {

Key read_key_file(const std::string& path) {
  const auto bytes = read_file_bytes(path);
  std::string text(bytes.begin(), bytes.end());
  std::size_t b = 0, e = text.size();
  while (b < e && std::isspace(static_cast<unsigned char>(text[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(text[e - 1]))) --e;
  text = text.substr(b, e - b);
  Key key{};
  if (text.size() != 2 * key.size())
    throw InputError(path, "not a meshmark key file (expected 64 hexadecimal digits, as written by `meshmark keygen`)");
  try {
    const auto raw = from_hex(text);
    std::memcpy(key.data(), raw.data(), key.size());
  } catch (const std::invalid_argument&) {
    throw InputError(path, "not a meshmark key file (expected 64 hexadecimal digits, as written by `meshmark keygen`)");
  }
  sodium_memzero(text.data(), text.size());
  return key;
}

bool key_file_exposed(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && (st.st_mode & 077) != 0;
}

std::string key_fingerprint(const Key& key) {
  static const char label[] = "meshmark key fingerprint v1";
  unsigned char h[32];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(label), sizeof label - 1,
                     key.data(), key.size());
  return "mmkey1:" + to_hex(h, sizeof h);
}

std::string key_file_text(const Key& key) { return to_hex(key.data(), key.size()) + "\n"; }

}  // namespace mm::cli
