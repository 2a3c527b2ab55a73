// Helpers for the store tests: a temporary folder and a clock the test steps by hand.
#pragma once
#include <stdlib.h>

#include <atomic>
#include <filesystem>
#include <string>

#include "store/store.h"

namespace mm::test {

struct TempDir {
  std::string path;
  TempDir() {
    char tmpl[] = "/tmp/mm-store-test-XXXXXX";
    path = ::mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    // Blobs are made read-only; the folder is ours, so removal still works.
    std::filesystem::remove_all(path, ec);
  }
  std::string operator/(const std::string& name) const { return path + "/" + name; }
};

struct StepClock {
  std::shared_ptr<std::atomic<store::Millis>> t = std::make_shared<std::atomic<store::Millis>>(1'700'000'000'000);
  store::Clock fn() const {
    auto p = t;
    return [p] { return p->load(); };
  }
  void advance(store::Millis ms) { *t += ms; }
  store::Millis now() const { return t->load(); }
};

inline keys::SecretKey test_master_key() {
  std::uint8_t b[32];
  for (int i = 0; i < 32; ++i) b[i] = static_cast<std::uint8_t>(0xA0 + i);
  return keys::SecretKey::from_bytes(b, 32);
}

inline store::StoreOptions options(const TempDir& dir, const StepClock* clock = nullptr) {
  store::StoreOptions o;
  o.db_path = dir / "meshmark.db";
  o.master_key = test_master_key();
  if (clock) o.clock = clock->fn();
  o.jitter_seed = 42;
  return o;
}

}  // namespace mm::test

#include <sqlite3.h>

#include <stdexcept>
#include <vector>

namespace mm::test {

// Runs SQL on its own connection; returns the first column of every row as text.
inline std::vector<std::string> raw_query(const std::string& db_path, const std::string& sql,
                                          std::string* error = nullptr) {
  sqlite3* db = nullptr;
  if (sqlite3_open(db_path.c_str(), &db) != SQLITE_OK) throw std::runtime_error("open " + db_path);
  sqlite3_busy_timeout(db, 10000);
  std::vector<std::string> rows;
  char* err = nullptr;
  int rc = sqlite3_exec(
      db, sql.c_str(),
      [](void* out, int n, char** vals, char**) {
        static_cast<std::vector<std::string>*>(out)->push_back(n > 0 && vals[0] ? vals[0] : "NULL");
        return 0;
      },
      &rows, &err);
  if (rc != SQLITE_OK) {
    std::string msg = err ? err : "error";
    sqlite3_free(err);
    sqlite3_close(db);
    if (error) {
      *error = msg;
      return rows;
    }
    throw std::runtime_error(msg);
  }
  if (error) error->clear();
  sqlite3_close(db);
  return rows;
}

}  // namespace mm::test
