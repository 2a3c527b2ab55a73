#include "store/blob_store.h"

#include <dirent.h>
#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>

#include "support/hex.h"
#include "support/sha256.h"

namespace mm::store {
namespace {

std::string errno_text() { return std::strerror(errno); }

void make_dir(const std::string& dir) {
  if (::mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST)
    throw BlobError("blob store: cannot create folder " + dir + ": " + errno_text());
}

void fsync_dir(const std::string& dir) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw BlobError("blob store: cannot open folder " + dir + ": " + errno_text());
  int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) throw BlobError("blob store: cannot fsync folder " + dir + ": " + errno_text());
}

bool write_all(int fd, const std::uint8_t* p, std::size_t n) {
  while (n > 0) {
    ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

std::string random_name() {
  unsigned char b[12];
  randombytes_buf(b, sizeof b);
  return support::to_hex(b, sizeof b);
}

// A temporary file in <root>/tmp, removed on destruction unless committed.
struct TempFile {
  std::string path;
  int fd = -1;
  explicit TempFile(const std::string& root) {
    path = root + "/tmp/" + random_name();
    fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) throw BlobError("blob store: cannot create " + path + ": " + errno_text());
  }
  ~TempFile() {
    if (fd >= 0) ::close(fd);
    if (!path.empty()) ::unlink(path.c_str());
  }
  // fsync, close, rename to dest, fsync dest folder.
  void commit(const std::string& dest_dir, const std::string& dest) {
    if (::fsync(fd) != 0) throw BlobError("blob store: cannot fsync " + path + ": " + errno_text());
    ::fchmod(fd, 0400);  // blobs are immutable
    ::close(fd);
    fd = -1;
    if (::rename(path.c_str(), dest.c_str()) != 0)
      throw BlobError("blob store: cannot rename into " + dest + ": " + errno_text());
    path.clear();
    fsync_dir(dest_dir);
  }
};

}  // namespace

bool is_sha256_hex(const std::string& s) {
  if (s.size() != 64) return false;
  for (char c : s)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

FsBlobStore::FsBlobStore(std::string root) : root_(std::move(root)) {
  if (sodium_init() < 0) throw BlobError("libsodium failed to initialize");
  while (root_.size() > 1 && root_.back() == '/') root_.pop_back();
  make_dir(root_);
  make_dir(root_ + "/tmp");
  remove_stale_temp_files();
}

std::string FsBlobStore::path(const std::string& sha256) const {
  if (!is_sha256_hex(sha256)) throw BlobError("blob store: not a sha256 hex name: '" + sha256.substr(0, 80) + "'");
  return root_ + "/" + sha256.substr(0, 2) + "/" + sha256;
}

bool FsBlobStore::contains(const std::string& sha256) const {
  struct stat st {};
  return ::stat(path(sha256).c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::uint64_t FsBlobStore::size(const std::string& sha256) const {
  struct stat st {};
  if (::stat(path(sha256).c_str(), &st) != 0) throw BlobError("blob " + sha256 + " is missing");
  return static_cast<std::uint64_t>(st.st_size);
}

std::string FsBlobStore::put(const std::uint8_t* data, std::size_t size) {
  std::string h = support::sha256_hex(data, size);
  if (contains(h)) return h;
  std::string dir = root_ + "/" + h.substr(0, 2);
  make_dir(dir);
  TempFile t(root_);
  if (!write_all(t.fd, data, size)) throw BlobError("blob store: cannot write " + t.path + ": " + errno_text());
  t.commit(dir, path(h));
  return h;
}

std::string FsBlobStore::put_file(const std::string& src) {
  // Copy into a temp file while hashing, so the hash is of exactly the bytes we keep, even if
  // the source changes under us.
  int in = ::open(src.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) throw BlobError(src + ": cannot open: " + errno_text());
  TempFile t(root_);
  support::Sha256 hash;
  std::vector<unsigned char> buf(1 << 16);
  for (;;) {
    ssize_t n = ::read(in, buf.data(), buf.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      std::string why = errno_text();
      ::close(in);
      throw BlobError(src + ": read error: " + why);
    }
    if (n == 0) break;
    hash.update(buf.data(), static_cast<std::size_t>(n));
    if (!write_all(t.fd, buf.data(), static_cast<std::size_t>(n))) {
      std::string why = errno_text();
      ::close(in);
      throw BlobError("blob store: cannot write " + t.path + ": " + why);
    }
  }
  ::close(in);
  std::string h = hash.hex();
  if (contains(h)) return h;  // TempFile removes its copy
  std::string dir = root_ + "/" + h.substr(0, 2);
  make_dir(dir);
  t.commit(dir, path(h));
  return h;
}

std::vector<std::uint8_t> FsBlobStore::get(const std::string& sha256) const {
  std::string p = path(sha256);
  int fd = ::open(p.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw BlobError("blob " + sha256 + " is missing (" + p + ": " + errno_text() + ")");
  struct stat st {};
  ::fstat(fd, &st);
  std::vector<std::uint8_t> out;
  out.reserve(static_cast<std::size_t>(st.st_size));
  std::vector<std::uint8_t> buf(1 << 16);
  for (;;) {
    ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      std::string why = errno_text();
      ::close(fd);
      throw BlobError("blob " + sha256 + ": read error: " + why);
    }
    if (n == 0) break;
    out.insert(out.end(), buf.begin(), buf.begin() + n);
  }
  ::close(fd);
  if (support::sha256_hex(out) != sha256)
    throw BlobError("blob " + sha256 + " is corrupted: its content no longer matches its hash");
  return out;
}

int FsBlobStore::remove_stale_temp_files() {
  // Only this process's own unfinished files could be in flight, and it has none at open time;
  // other processes' in-flight temp files are young: leave files modified in the last hour.
  std::string dir = root_ + "/tmp";
  DIR* d = ::opendir(dir.c_str());
  if (!d) return 0;
  int removed = 0;
  time_t now = ::time(nullptr);
  while (dirent* e = ::readdir(d)) {
    std::string name = e->d_name;
    if (name == "." || name == "..") continue;
    std::string p = dir + "/" + name;
    struct stat st {};
    if (::lstat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && now - st.st_mtime > 3600 &&
        ::unlink(p.c_str()) == 0)
      ++removed;
  }
  ::closedir(d);
  return removed;
}

}  // namespace mm::store
