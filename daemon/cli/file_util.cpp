#include "cli/file_util.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <system_error>

#include "meshio/mesh.h"
#include "support/atomic_file.h"

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

void write_file_atomic(const std::string& path, const std::string& data, unsigned mode) {
  try {
    support::write_file_atomic(path, data, mode);
  } catch (const std::system_error& e) {
    throw InputError(path, e.what());
  }
}

bool write_file_exclusive(const std::string& path, const std::string& data, unsigned mode) {
  try {
    return support::write_file_exclusive(path, data, mode);
  } catch (const std::system_error& e) {
    throw InputError(path, e.what());
  }
}

}  // namespace mm::cli
