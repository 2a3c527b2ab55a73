#include "store/copy_to_postgres.h"

#include <sqlite3.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <memory>

#include "store/blob_store.h"
#include "store/pg_blob_store.h"
#include "store/pg_db.h"
#include "store/sqlite_db.h"
#include "support/hex.h"

namespace mm::store {
namespace {

// Parents before children (foreign keys); job_counters after jobs, whose insert trigger counts
// each copied job once more: the copied counters replace what it counted.
constexpr const char* kTables[] = {"customers",  "customer_keys", "master_key_check", "assets",
                                   "polyhedra",  "jobs",          "issued_copies",    "detections",
                                   "audit_log",  "api_tokens",    "job_counters",     "job_events",
                                   "event_cursors"};
// Not moved: the migrations' own record, and the nodes of the machine the store leaves (runtime
// state; the fleet's nodes register themselves).
constexpr const char* kNotMoved[] = {"schema_version", "nodes", "leader"};
// Tables whose id column PostgreSQL generates: its sequence continues after the copied ids.
constexpr const char* kIdentity[] = {"customers",  "assets",    "polyhedra",  "jobs",      "issued_copies",
                                     "detections", "audit_log", "api_tokens", "job_events"};

// One SQLite value as PostgreSQL's text input reads it (bytea as \x hex).
pg::Param as_param(sqlite3_stmt* st, int c) {
  switch (sqlite3_column_type(st, c)) {
    case SQLITE_NULL: return std::nullopt;
    case SQLITE_INTEGER: return std::to_string(sqlite3_column_int64(st, c));
    case SQLITE_FLOAT: {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.17g", sqlite3_column_double(st, c));
      return std::string(buf);
    }
    case SQLITE_BLOB: {
      const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(st, c));
      return "\\x" + support::to_hex(p, static_cast<std::size_t>(sqlite3_column_bytes(st, c)));
    }
    default:
      return std::string(reinterpret_cast<const char*>(sqlite3_column_text(st, c)),
                         static_cast<std::size_t>(sqlite3_column_bytes(st, c)));
  }
}

// Every blob file under the FsBlobStore root (not its tmp/), checked against its name on the way.
std::int64_t copy_blobs(const std::string& blob_dir, pg::Connection& pgc) {
  namespace fs = std::filesystem;
  std::int64_t n = 0;
  if (!fs::exists(blob_dir)) return 0;
  const FsBlobStore blobs(blob_dir);
  for (const auto& shard : fs::directory_iterator(blob_dir)) {
    if (!shard.is_directory() || shard.path().filename() == "tmp") continue;
    for (const auto& f : fs::directory_iterator(shard.path())) {
      const std::string name = f.path().filename().string();
      if (!is_sha256_hex(name)) continue;
      const std::vector<std::uint8_t> bytes = blobs.get(name);  // BlobError if corrupted
      pg::put_blob(pgc, bytes.data(), bytes.size());
      ++n;
    }
  }
  return n;
}

}  // namespace

std::vector<CopiedTable> copy_sqlite_to_postgres(const std::string& sqlite_path, const std::string& blob_dir,
                                                 const std::string& conninfo) {
  sql::Db db(sqlite_path, 10000);
  pg::Connection pgc(conninfo);
  const int pg_version = pg::migrate(pgc);
  int sqlite_version = 0;
  {
    sql::Stmt v(db, "SELECT COALESCE(MAX(version), 0) FROM schema_version");
    v.step();
    sqlite_version = static_cast<int>(v.i64(0));
  }
  if (sqlite_version != pg_version)
    throw StoreError("cannot move " + sqlite_path + " (schema version " + std::to_string(sqlite_version) +
                     ") into PostgreSQL (schema version " + std::to_string(pg_version) +
                     "): open it with this meshmark first, which migrates it");
  // A table neither moved nor named as not moved (a later migration's) stops the move rather
  // than being left behind.
  {
    sql::Stmt t(db, "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%'");
    while (t.step()) {
      const std::string name = t.text(0);
      const auto listed = [&name](const auto& list) {
        return std::find(std::begin(list), std::end(list), name) != std::end(list);
      };
      if (!listed(kTables) && !listed(kNotMoved))
        throw StoreError("cannot move " + sqlite_path + ": its table " + name + " is not one this meshmark knows how "
                         "to move");
    }
  }
  std::vector<CopiedTable> out;
  sql::Tx snapshot(db, false);  // one snapshot of the SQLite store, even while a daemon writes to it
  pg::in_transaction(pgc, [&] {
    const pg::Result used = pgc.exec(
        "SELECT (SELECT COUNT(*) FROM customers) + (SELECT COUNT(*) FROM assets) + (SELECT COUNT(*) FROM jobs)");
    if (used.i64(0, 0) > 0)
      throw StoreError("the PostgreSQL database already holds customers, assets or jobs: a store moves only into "
                       "an empty one");
    for (const char* table : kTables) {
      if (std::string(table) == "job_counters") pgc.exec("DELETE FROM job_counters", {}, "replacing job counters");
      sqlite3_stmt* raw = nullptr;
      if (sqlite3_prepare_v2(db.get(), (std::string("SELECT * FROM ") + table).c_str(), -1, &raw, nullptr) != SQLITE_OK)
        throw StoreError("cannot read table " + std::string(table) + " of " + sqlite_path + ": " + sqlite3_errmsg(db.get()));
      const std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> st(raw, sqlite3_finalize);
      const int n = sqlite3_column_count(raw);
      // The same column names in both schemas (the migrations are kept in step).
      std::string cols, params;
      for (int c = 0; c < n; ++c) {
        cols += std::string(c ? ", " : "") + "\"" + sqlite3_column_name(raw, c) + "\"";
        params += (c ? ", $" : "$") + std::to_string(c + 1);
      }
      const std::string insert = std::string("INSERT INTO ") + table + " (" + cols + ") VALUES (" + params + ")";
      CopiedTable t{table, 0};
      int rc;
      while ((rc = sqlite3_step(raw)) == SQLITE_ROW) {
        std::vector<pg::Param> values;
        for (int c = 0; c < n; ++c) values.push_back(as_param(raw, c));
        pgc.exec(insert, values, std::string("copying ") + table);
        ++t.rows;
      }
      if (rc != SQLITE_DONE)
        throw StoreError("cannot read table " + std::string(table) + " of " + sqlite_path + ": " + sqlite3_errmsg(db.get()));
      out.push_back(t);
    }
    out.push_back({"blobs", copy_blobs(blob_dir, pgc)});
    for (const char* table : kIdentity)
      pgc.exec(std::string("SELECT setval(pg_get_serial_sequence('") + table + "', 'id'), COALESCE(MAX(id), 0) + 1, "
                   "false) FROM " + table,
               {}, std::string("continuing the ids of ") + table);
  });
  snapshot.commit();
  return out;
}

}  // namespace mm::store
