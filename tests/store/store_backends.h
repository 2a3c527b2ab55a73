// The store's contract tests run against each backend (River's driver tests are the model): a
// suite derives from BackendTest and opens its stores with open_store(dir, options); SQLite uses
// options.db_path, PostgreSQL a database of its own per temporary folder on a throwaway server
// (tests/common/postgres_server.h), blobs in the folder either way.
#pragma once
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/postgres_server.h"
#include "store/pg_db.h"
#include "store/pg_store.h"
#include "store/store.h"
#include "store_test_util.h"

namespace mm::test {

enum class Backend { sqlite, postgres };

inline std::string backend_name(const ::testing::TestParamInfo<Backend>& info) {
  return info.param == Backend::sqlite ? "sqlite" : "postgres";
}

// One server per test process, started by the first PostgreSQL test.
inline PostgresServer& shared_postgres() {
  static PostgresServer server;
  return server;
}

// Stores of one backend, for tests that take the backend as (part of) their parameter.
class BackendStores {
 public:
  explicit BackendStores(Backend b) : backend_(b) {}
  Backend backend() const { return backend_; }

  std::unique_ptr<store::Store> open_store(const TempDir& dir, store::StoreOptions o) {
    if (backend_ == Backend::sqlite) return store::open_sqlite_store(std::move(o));
    o.blob_dir = dir / "blobs";
    return store::open_postgres_store(conninfo(dir), std::move(o));
  }

  // The PostgreSQL database of `dir` (created on first use); empty for SQLite.
  std::string conninfo(const TempDir& dir) {
    if (backend_ == Backend::sqlite) return "";
    std::lock_guard<std::mutex> l(m_);
    auto [it, added] = databases_.emplace(dir.path, "t" + std::to_string(databases_.size()));
    if (added) {
      store::pg::Connection admin(shared_postgres().conninfo());
      admin.exec("DROP DATABASE IF EXISTS " + it->second);
      admin.exec("CREATE DATABASE " + it->second);
    }
    return shared_postgres().conninfo(it->second);
  }

  // SQL run past the store on its own connection: the first column of each row, or the
  // database's refusal in *error (thrown when error is null).
  std::vector<std::string> raw(const TempDir& dir, const std::string& sql, std::string* error = nullptr) {
    if (backend_ == Backend::sqlite) return raw_query(dir / "meshmark.db", sql, error);
    std::vector<std::string> rows;
    try {
      store::pg::Connection c(conninfo(dir));
      const store::pg::Result r = c.exec(sql);
      for (int i = 0; i < r.rows(); ++i) rows.push_back(r.is_null(i, 0) ? "NULL" : r.text(i, 0));
      if (error) error->clear();
    } catch (const store::StoreError& e) {
      if (!error) throw;
      *error = e.what();
    }
    return rows;
  }

 private:
  Backend backend_;
  std::mutex m_;
  std::map<std::string, std::string> databases_;
};

class BackendTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    if (GetParam() == Backend::postgres) MM_REQUIRE_POSTGRES();
  }
  std::unique_ptr<store::Store> open_store(const TempDir& dir, store::StoreOptions o) {
    return stores_.open_store(dir, std::move(o));
  }
  BackendStores& stores() { return stores_; }

 private:
  BackendStores stores_{GetParam()};
};

}  // namespace mm::test

#define MM_BACKENDS(suite)                                                                              \
  INSTANTIATE_TEST_SUITE_P(Backends, suite,                                                             \
                           ::testing::Values(mm::test::Backend::sqlite, mm::test::Backend::postgres), \
                           mm::test::backend_name)
