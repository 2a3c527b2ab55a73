// A PostgreSQL connection (libpq) for the store's PostgreSQL backend: statements with text
// parameters, results as text, transactions, LISTEN/NOTIFY and the schema migrations. Errors throw
// StoreError naming what was being done and the server's message (never the connection string,
// which may hold a password); the SQLSTATE is kept so callers can retry serialization failures.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "store/store.h"

struct pg_conn;
struct pg_result;

namespace mm::store::pg {

struct PgError : StoreError {
  PgError(const std::string& what, std::string state) : StoreError(what), sqlstate(std::move(state)) {}
  std::string sqlstate;  // "40001" serialization failure, "23505" unique violation, ...; "" if none
};

// A statement's rows, as text.
class Result {
 public:
  explicit Result(pg_result* r);
  ~Result();
  Result(Result&& other) noexcept;
  Result& operator=(Result&&) = delete;
  int rows() const;
  int columns() const;
  bool is_null(int row, int column) const;
  std::string text(int row, int column) const;
  std::int64_t i64(int row, int column) const;
  // Rows changed by an INSERT, UPDATE or DELETE.
  std::int64_t affected() const;

 private:
  pg_result* r_;
};

using Param = std::optional<std::string>;  // nullopt: SQL NULL

class Connection {
 public:
  // conninfo: "postgresql://..." or "host=... dbname=...". StoreError if it cannot connect.
  explicit Connection(const std::string& conninfo);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // One statement, parameters as $1, $2, ... (text; the server converts them). A connection the
  // server dropped (a restart, a failover) is made again before a statement outside a
  // transaction, its LISTENs renewed; inside one, the statement fails (the transaction is lost).
  Result exec(const std::string& sql, const std::vector<Param>& params = {}, const std::string& what = "");
  // Several statements without parameters, in one round trip (migrations).
  void exec_script(const std::string& sql, const std::string& what);

  // Subscribes this connection to a channel; wait_notification returns the channel of the next
  // notification, or nothing after timeout_ms.
  void listen(const std::string& channel);
  std::optional<std::string> wait_notification(int timeout_ms);

  bool ok() const;  // the connection is usable

  // in_transaction's bookkeeping: a connection is not silently remade inside a transaction.
  void set_in_transaction(bool open) { in_transaction_ = open; }

 private:
  void reconnect(const std::string& what);
  pg_conn* c_;
  bool in_transaction_ = false;
  std::vector<std::string> channels_;
};

// Runs fn between BEGIN and COMMIT; rolls back and rethrows if fn throws.
template <class F>
auto in_transaction(Connection& c, F&& fn, const std::string& isolation = "READ COMMITTED") {
  c.exec("BEGIN ISOLATION LEVEL " + isolation, {}, "starting a transaction");
  c.set_in_transaction(true);
  try {
    if constexpr (std::is_void_v<decltype(fn())>) {
      fn();
      c.exec("COMMIT", {}, "committing");
      c.set_in_transaction(false);
    } else {
      auto r = fn();
      c.exec("COMMIT", {}, "committing");
      c.set_in_transaction(false);
      return r;
    }
  } catch (...) {
    c.set_in_transaction(false);
    if (c.ok()) {
      try {
        c.exec("ROLLBACK", {}, "rolling back");
      } catch (const StoreError&) {
      }
    }
    throw;
  }
}

// Applies schema/postgres/NNNN_name.sql not yet recorded in schema_version, each in its own
// transaction under an advisory lock, so nodes starting together apply each migration once.
// Returns the schema version. StoreError if the database is newer than this binary knows.
int migrate(Connection& c);

}  // namespace mm::store::pg
