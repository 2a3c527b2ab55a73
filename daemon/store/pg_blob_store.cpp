#include "store/pg_blob_store.h"

#include <cerrno>
#include <cstring>
#include <fstream>

#include "store/pg_db.h"
#include "support/hex.h"
#include "support/sha256.h"

namespace mm::store {
namespace {

constexpr std::size_t kChunk = 1 << 20;

pg::Param bytea(const std::uint8_t* p, std::size_t n) { return "\\x" + support::to_hex(p, n); }

std::vector<std::uint8_t> bytes_of(const pg::Result& r, int row, int col) {
  const std::string t = r.text(row, col);
  if (t.rfind("\\x", 0) != 0) throw BlobError("blob store: a chunk is not bytea hex");
  return support::from_hex(t.substr(2));
}

std::string short_hash(const std::string& sha) { return sha.substr(0, 64); }

// Claims the blob's row; false if it is already stored (or was just stored by a transaction that
// committed while this one waited on the key).
bool claim_blob(pg::Connection& c, const std::string& sha, std::size_t size) {
  return c.exec("INSERT INTO blobs(sha256, size, created_at) VALUES($1, $2, mm_now_ms()) ON CONFLICT (sha256) "
                "DO NOTHING RETURNING sha256",
                {sha, std::to_string(size)}, "storing a blob")
             .rows() > 0;
}

void put_chunk(pg::Connection& c, const std::string& sha, std::size_t seq, const std::uint8_t* p, std::size_t n) {
  c.exec("INSERT INTO blob_chunks(sha256, seq, data) VALUES($1, $2, $3)", {sha, std::to_string(seq), bytea(p, n)},
         "storing a blob's bytes");
}

std::string cannot_read(const std::string& path) {
  return "blob store: cannot read " + path + ": " + std::strerror(errno);
}

}  // namespace

namespace pg {

std::string put_blob(Connection& c, const std::uint8_t* data, std::size_t size) {
  const std::string sha = support::sha256_hex(data, size);
  if (!claim_blob(c, sha, size)) return sha;
  for (std::size_t off = 0, seq = 0; off < size; off += kChunk, ++seq)
    put_chunk(c, sha, seq, data + off, std::min(kChunk, size - off));
  return sha;
}

std::string put_blob_file(Connection& c, const std::string& path) {
  // Two passes: the hash names the rows, so it is known before the first chunk is written.
  std::string sha;
  try {
    sha = support::sha256_file_hex(path);
  } catch (const std::system_error& e) {
    throw BlobError(std::string("blob store: ") + e.what());
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw BlobError(cannot_read(path));
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::size_t>(in.tellg());
  in.seekg(0);
  if (!claim_blob(c, sha, size)) return sha;
  std::vector<std::uint8_t> buf(kChunk);
  support::Sha256 check;
  std::size_t seq = 0, total = 0;
  while (in) {
    in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
    const auto n = static_cast<std::size_t>(in.gcount());
    if (n == 0) break;
    check.update(buf.data(), n);
    put_chunk(c, sha, seq++, buf.data(), n);
    total += n;
  }
  if (in.bad()) throw BlobError(cannot_read(path));
  // The file changed between the passes: refuse rather than store bytes under another's name.
  if (total != size || check.hex() != sha) throw BlobError("blob store: " + path + " changed while it was being stored");
  return sha;
}

}  // namespace pg

// A pooled connection, back to the pool when done unless it broke.
class PgBlobStore::Lease {
 public:
  explicit Lease(const PgBlobStore& s) : s_(s) {
    {
      std::lock_guard<std::mutex> l(s_.m_);
      if (!s_.idle_.empty()) {
        c_ = std::move(s_.idle_.back());
        s_.idle_.pop_back();
      }
    }
    if (!c_) c_ = std::make_unique<pg::Connection>(s_.conninfo_);
  }
  ~Lease() {
    if (!c_->ok()) return;
    std::lock_guard<std::mutex> l(s_.m_);
    s_.idle_.push_back(std::move(c_));
  }
  pg::Connection& operator*() { return *c_; }

 private:
  const PgBlobStore& s_;
  std::unique_ptr<pg::Connection> c_;
};

PgBlobStore::PgBlobStore(std::string conninfo, std::string cache_dir)
    : conninfo_(std::move(conninfo)), cache_(std::move(cache_dir)) {}
PgBlobStore::~PgBlobStore() = default;

std::string PgBlobStore::put(const std::uint8_t* data, std::size_t size) {
  Lease c(*this);
  return pg::in_transaction(*c, [&] { return pg::put_blob(*c, data, size); });
}

std::string PgBlobStore::put_file(const std::string& path) {
  Lease c(*this);
  return pg::in_transaction(*c, [&] { return pg::put_blob_file(*c, path); });
}

std::vector<std::uint8_t> PgBlobStore::get(const std::string& sha256) const {
  if (!is_sha256_hex(sha256)) throw BlobError("blob store: not a SHA-256: " + short_hash(sha256));
  Lease c(*this);
  // One snapshot for the row and its chunks (blobs are never changed, but may be pruned).
  return pg::in_transaction(
      *c,
      [&] {
        const pg::Result head =
            (*c).exec("SELECT size FROM blobs WHERE sha256 = $1", {sha256}, "reading a blob");
        if (head.rows() == 0) throw BlobError("blob store: no blob " + sha256);
        const auto size = static_cast<std::size_t>(head.i64(0, 0));
        std::vector<std::uint8_t> out;
        out.reserve(size);
        for (std::size_t seq = 0; out.size() < size; ++seq) {
          const pg::Result r = (*c).exec("SELECT data FROM blob_chunks WHERE sha256 = $1 AND seq = $2",
                                         {sha256, std::to_string(seq)}, "reading a blob");
          if (r.rows() == 0) break;
          const std::vector<std::uint8_t> part = bytes_of(r, 0, 0);
          if (part.empty()) break;
          out.insert(out.end(), part.begin(), part.end());
        }
        if (out.size() != size || support::sha256_hex(out) != sha256)
          throw BlobError("blob store: blob " + sha256 + " is corrupted (its bytes do not hash to its name)");
        return out;
      },
      "REPEATABLE READ");
}

bool PgBlobStore::contains(const std::string& sha256) const {
  if (!is_sha256_hex(sha256)) return false;
  Lease c(*this);
  return (*c).exec("SELECT 1 FROM blobs WHERE sha256 = $1", {sha256}, "looking up a blob").rows() > 0;
}

std::uint64_t PgBlobStore::size(const std::string& sha256) const {
  if (!is_sha256_hex(sha256)) throw BlobError("blob store: not a SHA-256: " + short_hash(sha256));
  Lease c(*this);
  const pg::Result r = (*c).exec("SELECT size FROM blobs WHERE sha256 = $1", {sha256}, "looking up a blob");
  if (r.rows() == 0) throw BlobError("blob store: no blob " + sha256);
  return static_cast<std::uint64_t>(r.i64(0, 0));
}

std::string PgBlobStore::path(const std::string& sha256) const {
  if (!cache_.contains(sha256)) cache_.put(get(sha256));
  return cache_.path(sha256);
}

}  // namespace mm::store
