#include "store/sqlite_db.h"

#include "support/fault_injection.h"

#include <sys/vfs.h>

#include <chrono>
#include <filesystem>
#include <thread>
#include <unordered_map>

namespace mm::store::sql {
namespace {
[[noreturn]] void fail(sqlite3* db, const std::string& what) {
  throw StoreError(what + ": " + (db ? sqlite3_errmsg(db) : "out of memory"));
}
}  // namespace

const char* network_filesystem_name(long f_type) {
  switch (static_cast<unsigned long>(f_type) & 0xffffffffUL) {
    case 0x6969: return "NFS";
    case 0x517B: return "SMB";
    case 0xFF534D42: return "CIFS";
    case 0xFE534D42: return "SMB2";
    case 0x00C36400: return "Ceph";
    case 0x5346414F: return "AFS";
    case 0x73757245: return "Coda";
    case 0x564C: return "NCP";
    case 0x0BD00BD0: return "Lustre";
    case 0x47504653: return "GPFS";
    case 0x01161970: return "GFS2";
    case 0x7461636F: return "OCFS2";
    default: return nullptr;
  }
}

void require_local_filesystem(const std::string& db_path) {
  namespace fs = std::filesystem;
  fs::path dir = fs::absolute(fs::path(db_path)).parent_path();
  struct statfs st {};
  if (statfs(dir.c_str(), &st) != 0) return;  // the open that follows names the real problem
  if (const char* name = network_filesystem_name(static_cast<long>(st.f_type)))
    throw StoreError("cannot open database " + db_path + ": its folder is on a network file system (" + name +
                     "); SQLite's write-ahead log needs shared memory on one machine, so the store must "
                     "be on a local disk (docs/store.md)");
}

namespace {
constexpr int kCheckpointPages = 1000;  // SQLite's own autocheckpoint threshold

// Replaces SQLite's automatic checkpoint (see Db). Runs after a commit, its write lock released.
int checkpoint_under_write_lock(void* self, sqlite3*, const char*, int pages) {
  if (pages >= kCheckpointPages) static_cast<Db*>(self)->checkpoint();
  return SQLITE_OK;
}
}  // namespace

bool Db::checkpoint() {
  if (!guard_) {
    if (sqlite3_open_v2(path_.c_str(), &guard_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
      sqlite3_close_v2(guard_);
      guard_ = nullptr;
      return false;
    }
    sqlite3_wal_autocheckpoint(guard_, 0);
    sqlite3_busy_timeout(guard_, 200);
  }
  // Nobody can commit (and so reset the WAL) while the guard holds the write lock.
  if (sqlite3_exec(guard_, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) != SQLITE_OK) return false;
  int rc = sqlite3_wal_checkpoint_v2(db_, "main", SQLITE_CHECKPOINT_PASSIVE, nullptr, nullptr);
  sqlite3_exec(guard_, "ROLLBACK", nullptr, nullptr, nullptr);
  return rc == SQLITE_OK;
}

namespace {
// One writer turn per database file in this process, shared by its connections.
std::shared_ptr<std::timed_mutex> writer_turn(const std::string& path) {
  static std::mutex m;
  static std::unordered_map<std::string, std::weak_ptr<std::timed_mutex>> turns;
  std::error_code ec;
  std::string key = std::filesystem::weakly_canonical(std::filesystem::absolute(path), ec).string();
  if (ec) key = path;
  std::lock_guard<std::mutex> l(m);
  auto& w = turns[key];
  auto t = w.lock();
  if (!t) w = t = std::make_shared<std::timed_mutex>();
  return t;
}
}  // namespace

bool Db::lock_writer() { return writer_->try_lock_for(std::chrono::milliseconds(busy_timeout_ms_)); }
void Db::unlock_writer() { writer_->unlock(); }

sqlite3_stmt* Db::take_statement(const char* sql) {
  auto it = statements_.find(sql);
  if (it == statements_.end()) return nullptr;
  sqlite3_stmt* st = it->second;
  statements_.erase(it);  // in use: a nested Stmt of the same text prepares its own
  return st;
}

void Db::return_statement(const char* sql, sqlite3_stmt* st) {
  sqlite3_reset(st);
  sqlite3_clear_bindings(st);
  // Bounded: statements whose text varies (lists with filters) do not pile up.
  if (statements_.size() >= 64 || !statements_.emplace(sql, st).second) sqlite3_finalize(st);
}

Db::Db(const std::string& path, int busy_timeout_ms)
    : writer_(writer_turn(path)), path_(path), busy_timeout_ms_(busy_timeout_ms) {
  require_local_filesystem(path);
  int rc = sqlite3_open_v2(path.c_str(), &db_,
                           SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close_v2(db_);
    db_ = nullptr;
    throw StoreError("cannot open database " + path + ": " + msg);
  }
  sqlite3_extended_result_codes(db_, 1);
  sqlite3_busy_timeout(db_, busy_timeout_ms);
  sqlite3_wal_hook(db_, checkpoint_under_write_lock, this);
}

Db::~Db() {
  for (auto& [sql, st] : statements_) sqlite3_finalize(st);
  if (guard_) sqlite3_close_v2(guard_);
  if (db_) sqlite3_close_v2(db_);
}

// sqlite3_exec's result code; `msg` gets the error text when it is not SQLITE_OK.
int Db::exec_once(const std::string& sql, std::string& msg) {
  char* err = nullptr;
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err);
  if (rc != SQLITE_OK) msg = err ? err : sqlite3_errmsg(db_);
  sqlite3_free(err);
  return rc;
}

void Db::exec(const std::string& sql, const char* what) {
  std::string msg;
  if (exec_once(sql, msg) != SQLITE_OK) throw StoreError(std::string(what) + ": " + msg);
}

void Db::exec_retrying_busy(const std::string& sql, const char* what) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(busy_timeout_ms_);
  for (std::string msg;;) {
    const int rc = exec_once(sql, msg);
    if (rc == SQLITE_OK) return;
    if ((rc & 0xff) != SQLITE_BUSY || std::chrono::steady_clock::now() >= deadline)
      throw StoreError(std::string(what) + ": " + msg);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

Stmt::Stmt(Db& db, const char* sql) : db_(db), sql_(sql) {
  st_ = db.take_statement(sql);
  if (!st_ && sqlite3_prepare_v3(db.get(), sql, -1, SQLITE_PREPARE_PERSISTENT, &st_, nullptr) != SQLITE_OK)
    fail(db.get(), "preparing statement");
}
Stmt::~Stmt() {
  if (st_) db_.return_statement(sql_.c_str(), st_);
}

Stmt& Stmt::bind(int i, std::int64_t v) {
  if (sqlite3_bind_int64(st_, i, v) != SQLITE_OK) fail(db_.get(), "bind");
  return *this;
}
Stmt& Stmt::bind(int i, double v) {
  if (sqlite3_bind_double(st_, i, v) != SQLITE_OK) fail(db_.get(), "bind");
  return *this;
}
Stmt& Stmt::bind(int i, const std::string& v) {
  if (sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT) != SQLITE_OK)
    fail(db_.get(), "bind");
  return *this;
}
Stmt& Stmt::bind(int i, const std::vector<std::uint8_t>& v) {
  if (sqlite3_bind_blob(st_, i, v.empty() ? "" : static_cast<const void*>(v.data()),
                        static_cast<int>(v.size()), SQLITE_TRANSIENT) != SQLITE_OK)
    fail(db_.get(), "bind");
  return *this;
}
Stmt& Stmt::bind_null(int i) {
  if (sqlite3_bind_null(st_, i) != SQLITE_OK) fail(db_.get(), "bind");
  return *this;
}

bool Stmt::step() {
  int rc = sqlite3_step(st_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  fail(db_.get(), "database statement failed");
}
void Stmt::run() {
  while (step()) {
  }
}
int Stmt::changes() const { return sqlite3_changes(db_.get()); }

bool Stmt::is_null(int c) const { return sqlite3_column_type(st_, c) == SQLITE_NULL; }
std::int64_t Stmt::i64(int c) const { return sqlite3_column_int64(st_, c); }
double Stmt::f64(int c) const { return sqlite3_column_double(st_, c); }
std::string Stmt::text(int c) const {
  auto p = reinterpret_cast<const char*>(sqlite3_column_text(st_, c));
  return p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(st_, c))) : std::string();
}
std::vector<std::uint8_t> Stmt::blob(int c) const {
  auto p = static_cast<const std::uint8_t*>(sqlite3_column_blob(st_, c));
  int n = sqlite3_column_bytes(st_, c);
  return p ? std::vector<std::uint8_t>(p, p + n) : std::vector<std::uint8_t>();
}
std::optional<std::int64_t> Stmt::opt_i64(int c) const {
  if (is_null(c)) return std::nullopt;
  return i64(c);
}
std::optional<double> Stmt::opt_f64(int c) const {
  if (is_null(c)) return std::nullopt;
  return f64(c);
}

Tx::Tx(Db& db, bool immediate) : db_(db), immediate_(immediate) {
  if (immediate) {
    if (!db_.lock_writer()) throw StoreError("begin transaction: database is locked (by this process)");
    writer_ = true;
  }
  try {
    db_.exec(immediate ? "BEGIN IMMEDIATE" : "BEGIN", "begin transaction");
  } catch (...) {
    if (writer_) db_.unlock_writer();
    throw;
  }
}
Tx::~Tx() {
  if (!done_) sqlite3_exec(db_.get(), "ROLLBACK", nullptr, nullptr, nullptr);
  if (writer_) db_.unlock_writer();
}
void Tx::commit() {
  // Statements read only partly (a RETURNING row, a single-row SELECT) still count as "in
  // progress" and would make COMMIT fail; their results are already copied out, so reset them.
  for (sqlite3_stmt* s = sqlite3_next_stmt(db_.get(), nullptr); s; s = sqlite3_next_stmt(db_.get(), s))
    if (sqlite3_stmt_busy(s)) sqlite3_reset(s);
  if (immediate_ && support::injected_fault("MESHMARK_FAIL_DB_WRITE"))  // tests only
    throw StoreError("commit: disk I/O error (injected: MESHMARK_FAIL_DB_WRITE)");
  db_.exec("COMMIT", "commit");
  done_ = true;
  if (writer_) {
    writer_ = false;
    db_.unlock_writer();
  }
}

}  // namespace mm::store::sql
