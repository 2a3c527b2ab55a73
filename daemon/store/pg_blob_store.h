// Blobs in the PostgreSQL database, so every node of a fleet reads the same originals, control
// polyhedra and bases without a shared folder (docs/fleet.md). A blob is one `blobs` row (its
// SHA-256 and size) and its bytes in 1 MiB `blob_chunks` rows, written in one transaction: a blob
// is either absent or whole. The chunk column is STORAGE EXTERNAL (schema/postgres/0009_blobs.sql):
// meshes and streams are already compact, so PostgreSQL does not try to compress them again.
#pragma once
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "store/blob_store.h"

namespace mm::store {
namespace pg {
class Connection;
// Writes a blob inside the caller's transaction on c (so a row pointing at it can commit with it);
// returns its SHA-256. Bytes already stored are not written again.
std::string put_blob(Connection& c, const std::uint8_t* data, std::size_t size);
// The same for a file's content, read in chunks (never whole). BlobError naming the file if it
// cannot be read.
std::string put_blob_file(Connection& c, const std::string& path);
}  // namespace pg

// The BlobStore over a database: put() commits before it returns (the rule of blob_store.h);
// path() copies a blob into cache_dir (an FsBlobStore of this node) once and returns that file.
// Connections are pooled: concurrent readers do not queue behind one another or the queue's.
class PgBlobStore : public BlobStore {
 public:
  PgBlobStore(std::string conninfo, std::string cache_dir);
  ~PgBlobStore() override;
  std::string put(const std::uint8_t* data, std::size_t size) override;
  using BlobStore::put;
  std::string put_file(const std::string& path) override;
  std::vector<std::uint8_t> get(const std::string& sha256) const override;
  bool contains(const std::string& sha256) const override;
  std::uint64_t size(const std::string& sha256) const override;
  std::string path(const std::string& sha256) const override;

 private:
  class Lease;
  std::string conninfo_;
  mutable FsBlobStore cache_;
  mutable std::mutex m_;
  mutable std::vector<std::unique_ptr<pg::Connection>> idle_;
};

}  // namespace mm::store
