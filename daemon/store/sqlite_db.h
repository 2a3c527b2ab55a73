// Thin RAII over the SQLite C API for the store's own use (not part of the Store interface).
#pragma once
#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "store/store.h"

namespace mm::store::sql {

// The name of a network file system's statfs() magic number, or nullptr for a local one.
const char* network_filesystem_name(long f_type);
// StoreError naming the path when the database's folder is on a network file system: SQLite's
// write-ahead log needs shared memory between the processes of one machine.
void require_local_filesystem(const std::string& db_path);

// One connection. Checkpoints are never automatic: SQLite up to 3.51.2 (Debian 12 has 3.40.1)
// has a data race, the "WAL-reset bug", in which a checkpoint that starts while another
// connection's commit resets the write-ahead log can corrupt the database. So, after a commit
// leaves 1000 pages in the log, checkpoint() runs the checkpoint while a second connection holds
// the write lock: no commit, and so no reset, can overlap it.
class Db {
 public:
  Db(const std::string& path, int busy_timeout_ms);
  ~Db();
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;
  sqlite3* get() const { return db_; }
  void exec(const std::string& sql, const char* what);  // StoreError naming `what`
  // The same, retried while SQLite answers SQLITE_BUSY without waiting, for up to the busy
  // timeout. Changing the journal mode needs an exclusive lock, and SQLite may refuse it at once
  // (no busy handler) while another connection opening the same new database holds a lock: four
  // concurrent openers failed "enabling WAL: database is locked" about once in 30 runs.
  void exec_retrying_busy(const std::string& sql, const char* what);
  std::string path() const { return path_; }
  // A passive checkpoint under the write lock; false when the lock was not free within 200 ms
  // (the next commit tries again).
  bool checkpoint();
  // Write transactions of one process on one database file take turns here before SQLite's
  // lock: threads then queue without SQLite's busy handler, which sleeps for milliseconds.
  // false when the busy timeout passed first.
  bool lock_writer();
  void unlock_writer();

  // Prepared statements kept for reuse, by SQL text (Stmt takes and returns them).
  sqlite3_stmt* take_statement(const char* sql);
  void return_statement(const char* sql, sqlite3_stmt* st);

 private:
  int exec_once(const std::string& sql, std::string& msg);
  std::shared_ptr<std::timed_mutex> writer_;
  std::unordered_map<std::string, sqlite3_stmt*> statements_;
  sqlite3* db_ = nullptr;
  sqlite3* guard_ = nullptr;  // holds the write lock during checkpoint()
  std::string path_;
  int busy_timeout_ms_ = 0;
};

class Stmt {
 public:
  Stmt(Db& db, const char* sql);
  ~Stmt();
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  Stmt& bind(int i, std::int64_t v);
  Stmt& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Stmt& bind(int i, double v);
  Stmt& bind(int i, const std::string& v);
  Stmt& bind(int i, const char* v) { return bind(i, std::string(v)); }
  Stmt& bind(int i, const std::vector<std::uint8_t>& v);
  Stmt& bind_null(int i);
  template <class T>
  Stmt& bind(int i, const std::optional<T>& v) {
    return v ? bind(i, *v) : bind_null(i);
  }

  bool step();      // true: a row is ready; false: done. StoreError on failure.
  void run();       // step to completion
  int changes() const;

  bool is_null(int col) const;
  std::int64_t i64(int col) const;
  double f64(int col) const;
  std::string text(int col) const;
  std::vector<std::uint8_t> blob(int col) const;
  std::optional<std::int64_t> opt_i64(int col) const;
  std::optional<double> opt_f64(int col) const;

 private:
  Db& db_;
  sqlite3_stmt* st_ = nullptr;
  std::string sql_;
};

// BEGIN IMMEDIATE ... COMMIT (holding the process's writer turn, Db::lock_writer); rolls back
// when destroyed without commit().
class Tx {
 public:
  explicit Tx(Db& db, bool immediate = true);
  ~Tx();
  void commit();

 private:
  Db& db_;
  bool immediate_ = true;  // a write transaction
  bool done_ = false;
  bool writer_ = false;  // holds db_'s writer turn
};

}  // namespace mm::store::sql
