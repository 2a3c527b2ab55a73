#include "cli/file_util.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include "meshio/mesh.h"

namespace mm::cli {

std::vector<std::uint8_t> read_file_bytes(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) throw InputError(path, "is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<std::uint8_t> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) throw InputError(path, "read error");
  return bytes;
}

namespace {

// Writes `data` to a fresh temporary file beside `path` with `mode`, fsynced; returns its name.
std::string write_temporary(const std::string& path, const std::string& data, unsigned mode) {
  namespace fs = std::filesystem;
  fs::path target(path);
  fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::string tmpl = (dir / ("." + target.filename().string() + ".tmpXXXXXX")).string();
  int fd = mkstemp(tmpl.data());
  if (fd < 0) throw InputError(path, std::string("cannot create: ") + std::strerror(errno));
  bool ok = fchmod(fd, mode) == 0;
  const char* p = data.data();
  std::size_t left = data.size();
  while (ok && left > 0) {
    ssize_t w = ::write(fd, p, left);
    if (w < 0 && errno == EINTR) continue;
    ok = w > 0;
    if (ok) { p += w; left -= static_cast<std::size_t>(w); }
  }
  int err = ok ? 0 : errno;
  if (ok && fsync(fd) != 0) ok = false, err = errno;
  ::close(fd);
  if (!ok) {
    ::unlink(tmpl.c_str());
    throw InputError(path, std::string("cannot write: ") + std::strerror(err ? err : EIO));
  }
  return tmpl;
}

}  // namespace

void write_file_atomic(const std::string& path, const std::string& data, unsigned mode) {
  const std::string tmp = write_temporary(path, data, mode);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw InputError(path, std::string("cannot write: ") + std::strerror(err));
  }
}

bool write_file_exclusive(const std::string& path, const std::string& data, unsigned mode) {
  const std::string tmp = write_temporary(path, data, mode);
  const int rc = ::link(tmp.c_str(), path.c_str());
  const int err = errno;
  ::unlink(tmp.c_str());
  if (rc == 0) return true;
  if (err == EEXIST) return false;
  throw InputError(path, std::string("cannot write: ") + std::strerror(err));
}

std::string sha256_hex(const std::uint8_t* data, std::size_t size) {
  unsigned char h[crypto_hash_sha256_BYTES];
  crypto_hash_sha256(h, data, size);
  return to_hex(h, sizeof h);
}

std::string sha256_file_hex(const std::string& path) {
  auto bytes = read_file_bytes(path);
  return sha256_hex(bytes.data(), bytes.size());
}

std::string to_hex(const std::uint8_t* data, std::size_t size) {
  static const char* digits = "0123456789abcdef";
  std::string s(2 * size, '0');
  for (std::size_t i = 0; i < size; ++i) {
    s[2 * i] = digits[data[i] >> 4];
    s[2 * i + 1] = digits[data[i] & 15];
  }
  return s;
}

std::vector<std::uint8_t> from_hex(const std::string& hex) {
  std::vector<std::uint8_t> out(hex.size() / 2);
  std::size_t len = 0;
  if (hex.size() % 2 != 0 ||
      sodium_hex2bin(out.data(), out.size(), hex.data(), hex.size(), nullptr, &len, nullptr) != 0 ||
      len != out.size())
    throw std::invalid_argument("not a hexadecimal string");
  return out;
}

}  // namespace mm::cli
