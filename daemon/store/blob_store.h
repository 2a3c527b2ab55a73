// Content-addressed file storage: a blob's name is the SHA-256 of its bytes (64 lower-case hex).
//
// The interface is deliberately narrow (put, get, contains, path) so an object store (S3 and the
// like) can replace the filesystem later without touching job handlers. The rule every
// implementation keeps: put() returns only after the bytes are durable, so a database row may
// point at the hash as soon as put() has returned; never before.
#pragma once
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace mm::store {

struct BlobError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class BlobStore {
 public:
  virtual ~BlobStore() = default;
  // Store bytes; returns their SHA-256 hex. Storing the same bytes again is a cheap no-op.
  virtual std::string put(const std::uint8_t* data, std::size_t size) = 0;
  std::string put(const std::string& bytes) {
    return put(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  std::string put(const std::vector<std::uint8_t>& bytes) { return put(bytes.data(), bytes.size()); }
  // Store a file's content (streamed, not read whole into memory); returns its SHA-256 hex.
  virtual std::string put_file(const std::string& path) = 0;
  // The bytes of a blob, verified against the hash (BlobError if missing or corrupted).
  virtual std::vector<std::uint8_t> get(const std::string& sha256) const = 0;
  virtual bool contains(const std::string& sha256) const = 0;
  virtual std::uint64_t size(const std::string& sha256) const = 0;  // BlobError if missing
  // A local file path with the blob's bytes (for libraries that read files). A remote store
  // would download to a cache; the filesystem store returns the blob file itself (read-only).
  virtual std::string path(const std::string& sha256) const = 0;
};

// Blobs as files <root>/<first two hex>/<full hex>. put: write <root>/tmp/<random>, fsync it,
// rename into place, fsync the destination folder. tmp/ is never read as blobs; leftovers from a
// crash are removed by remove_stale_temp_files() (called on open).
class FsBlobStore : public BlobStore {
 public:
  explicit FsBlobStore(std::string root);  // creates root (0700) if missing
  std::string put(const std::uint8_t* data, std::size_t size) override;
  using BlobStore::put;
  std::string put_file(const std::string& path) override;
  std::vector<std::uint8_t> get(const std::string& sha256) const override;
  bool contains(const std::string& sha256) const override;
  std::uint64_t size(const std::string& sha256) const override;
  std::string path(const std::string& sha256) const override;
  const std::string& root() const { return root_; }
  int remove_stale_temp_files();  // returns how many were removed

 private:
  std::string root_;
};

bool is_sha256_hex(const std::string& s);

}  // namespace mm::store
