#include "support/atomic_file.h"

#include "support/fault_injection.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <system_error>

namespace mm::support {

namespace {

constexpr const char* kTemporaryTag = ".tmp.";
constexpr std::size_t kUniqueChars = 6;  // mkstemp's XXXXXX

[[noreturn]] void fail(int err, const char* step) { throw std::system_error(err, std::generic_category(), step); }

std::filesystem::path folder_of(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parent.empty() ? std::filesystem::path(".") : parent;
}

// A written, fsynced temporary beside `path`; its name.
std::string write_temporary(const std::string& path, std::string_view bytes, unsigned mode) {
  std::string name = (folder_of(path) / ("." + std::filesystem::path(path).filename().string() + kTemporaryTag +
                                         std::string(kUniqueChars, 'X')))
                         .string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) fail(errno, "cannot create temporary file");
  auto give_up = [&](const char* step) {
    const int err = errno;
    ::close(fd);
    ::unlink(name.c_str());
    fail(err, step);
  };
  if (::fchmod(fd, static_cast<mode_t>(mode)) != 0) give_up("cannot set the mode");
  if (injected_fault("MESHMARK_FAIL_WRITE")) {  // tests only (support/fault_injection.h)
    errno = ENOSPC;
    give_up("cannot write");
  }
  const char* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t w = ::write(fd, p, left);
    if (w < 0) {
      if (errno == EINTR) continue;
      give_up("cannot write");
    }
    p += w;
    left -= static_cast<std::size_t>(w);
  }
  if (::fsync(fd) != 0) give_up("cannot fsync");
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(name.c_str());
    fail(err, "cannot close");
  }
  return name;
}

// Makes a rename or link durable; a failure here cannot un-write the file, so it is ignored.
void sync_folder(const std::string& path) {
  const int dfd = ::open(folder_of(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

}  // namespace

void write_file_atomic(const std::string& path, std::string_view bytes, unsigned mode) {
  const std::string tmp = write_temporary(path, bytes, mode);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    fail(err, "cannot rename into place");
  }
  sync_folder(path);
}

void write_file_atomic(const std::string& path, const std::vector<std::uint8_t>& bytes, unsigned mode) {
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), mode);
}

bool write_file_exclusive(const std::string& path, std::string_view bytes, unsigned mode) {
  const std::string tmp = write_temporary(path, bytes, mode);
  const int rc = ::link(tmp.c_str(), path.c_str());
  const int err = errno;
  ::unlink(tmp.c_str());
  if (rc == 0) {
    sync_folder(path);
    return true;
  }
  if (err == EEXIST) return false;
  fail(err, "cannot link into place");
}

bool is_atomic_write_temporary(const std::string& filename) {
  const std::size_t pos = filename.rfind(kTemporaryTag);
  return filename.size() > 1 && filename[0] == '.' && pos != std::string::npos &&
         pos + std::char_traits<char>::length(kTemporaryTag) + kUniqueChars == filename.size();
}

}  // namespace mm::support
