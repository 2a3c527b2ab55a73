#include "store/pg_db.h"

#include <libpq-fe.h>
#include <poll.h>

#include <chrono>

#include "store/migrations.h"

namespace mm::store::pg {
namespace {

std::string message_of(const pg_conn* c) {
  std::string m = PQerrorMessage(c);
  while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
  return m;
}

}  // namespace

Result::Result(pg_result* r) : r_(r) {}
Result::~Result() {
  if (r_) PQclear(r_);
}
Result::Result(Result&& other) noexcept : r_(other.r_) { other.r_ = nullptr; }
int Result::rows() const { return PQntuples(r_); }
int Result::columns() const { return PQnfields(r_); }
bool Result::is_null(int row, int column) const { return PQgetisnull(r_, row, column) != 0; }
std::string Result::text(int row, int column) const {
  return std::string(PQgetvalue(r_, row, column), static_cast<std::size_t>(PQgetlength(r_, row, column)));
}
std::int64_t Result::i64(int row, int column) const { return std::stoll(text(row, column)); }
std::int64_t Result::affected() const {
  const char* n = PQcmdTuples(r_);
  return n && *n ? std::stoll(n) : 0;
}

Connection::Connection(const std::string& conninfo) : c_(PQconnectdb(conninfo.c_str())) {
  if (!c_ || PQstatus(c_) != CONNECTION_OK) {
    const std::string why = c_ ? message_of(c_) : "out of memory";
    if (c_) PQfinish(c_);
    c_ = nullptr;
    throw StoreError("PostgreSQL: cannot connect: " + why);
  }
  // Notices ("already exists, skipping") are not errors and go nowhere; times as the store writes
  // them, whatever the server's defaults.
  PQsetNoticeProcessor(c_, [](void*, const char*) {}, nullptr);
  exec("SET TIME ZONE 'UTC'", {}, "setting the session's time zone");
}

Connection::~Connection() {
  if (c_) PQfinish(c_);
}

bool Connection::ok() const { return c_ && PQstatus(c_) == CONNECTION_OK; }

namespace {

// A statement's result, or PgError with what was being done, the server's message and SQLSTATE.
Result checked(pg_conn* c, pg_result* r, const std::string& what) {
  const auto status = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return Result(r);
  std::string state, message;
  if (r) {
    if (const char* s = PQresultErrorField(r, PG_DIAG_SQLSTATE)) state = s;
    message = PQresultErrorMessage(r);
    PQclear(r);
  }
  if (message.empty()) message = message_of(c);
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  throw PgError("PostgreSQL: " + (what.empty() ? std::string("a statement") : what) + ": " + message, state);
}

}  // namespace

void Connection::reconnect(const std::string& what) {
  if (in_transaction_)
    throw PgError("PostgreSQL: " + (what.empty() ? std::string("a statement") : what) +
                      ": the connection was lost inside a transaction: " + message_of(c_),
                  "08006");
  PQreset(c_);
  if (PQstatus(c_) != CONNECTION_OK) throw PgError("PostgreSQL: cannot reconnect: " + message_of(c_), "08006");
  exec("SET TIME ZONE 'UTC'", {}, "setting the session's time zone");
  const std::vector<std::string> channels = std::move(channels_);
  channels_.clear();
  for (const auto& ch : channels) listen(ch);
}

Result Connection::exec(const std::string& sql, const std::vector<Param>& params, const std::string& what) {
  if (PQstatus(c_) != CONNECTION_OK) reconnect(what);
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const Param& p : params) values.push_back(p ? p->c_str() : nullptr);
  const auto run = [&] {
    return checked(c_, PQexecParams(c_, sql.c_str(), static_cast<int>(values.size()), nullptr, values.data(), nullptr,
                                    nullptr, 0),
                   what);
  };
  try {
    return run();
  } catch (const PgError&) {
    // A session the server ended is often noticed only by the statement that finds it gone. A
    // BEGIN or a read changed nothing, so it runs again on a new session; a write outside a
    // transaction is not repeated (it may have run).
    const bool harmless = sql.rfind("BEGIN", 0) == 0 || sql.rfind("SELECT", 0) == 0 || sql.rfind("SET ", 0) == 0;
    if (in_transaction_ || PQstatus(c_) == CONNECTION_OK || !harmless) throw;
  }
  reconnect(what);
  return run();
}

void Connection::exec_script(const std::string& sql, const std::string& what) {
  if (PQstatus(c_) != CONNECTION_OK) reconnect(what);
  // PQexec runs every statement of the string; the result is the last one's, an error stops it.
  checked(c_, PQexec(c_, sql.c_str()), what);
}

void Connection::listen(const std::string& channel) {
  char* quoted = PQescapeIdentifier(c_, channel.c_str(), channel.size());
  if (!quoted) throw StoreError("PostgreSQL: bad channel name: " + message_of(c_));
  const std::string sql = std::string("LISTEN ") + quoted;
  PQfreemem(quoted);
  exec(sql, {}, "listening on " + channel);
  channels_.push_back(channel);
}

std::optional<std::string> Connection::wait_notification(int timeout_ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  if (PQstatus(c_) != CONNECTION_OK) reconnect("waiting for a notification");
  for (;;) {
    if (PQconsumeInput(c_) == 0 && PQstatus(c_) != CONNECTION_OK)
      throw PgError("PostgreSQL: the connection was lost while waiting for a notification: " + message_of(c_), "08006");
    if (PGnotify* n = PQnotifies(c_)) {
      std::string channel = n->relname;
      PQfreemem(n);
      return channel;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now()).count();
    if (left <= 0) return std::nullopt;
    struct pollfd p{PQsocket(c_), POLLIN, 0};
    if (p.fd < 0) throw StoreError("PostgreSQL: the connection is closed: " + message_of(c_));
    ::poll(&p, 1, static_cast<int>(left));
  }
}

int migrate(Connection& c) {
  const auto& ms = embedded_postgres_migrations();
  const int latest = ms.empty() ? 0 : ms.back().version;
  // One node at a time: the others wait here, then find every migration applied.
  constexpr const char* kLock = "SELECT pg_advisory_xact_lock(7213409511)";
  in_transaction(c, [&] {
    c.exec(kLock, {}, "waiting for the migration lock");
    c.exec("CREATE TABLE IF NOT EXISTS schema_version (version integer PRIMARY KEY, name text NOT NULL, "
           "applied_at bigint NOT NULL)",
           {}, "creating schema_version");
  });
  for (const Migration& m : ms) {
    in_transaction(c, [&] {
      c.exec(kLock, {}, "waiting for the migration lock");
      if (c.exec("SELECT 1 FROM schema_version WHERE version = $1", {std::to_string(m.version)}, "reading schema_version").rows())
        return;
      c.exec_script(m.sql, std::string("applying migration ") + m.name);
      c.exec("INSERT INTO schema_version(version, name, applied_at) VALUES ($1, $2, "
             "(extract(epoch FROM clock_timestamp()) * 1000)::bigint)",
             {std::to_string(m.version), std::string(m.name)}, "recording migration " + std::string(m.name));
    });
  }
  const Result v = c.exec("SELECT COALESCE(MAX(version), 0) FROM schema_version", {}, "reading schema_version");
  const int version = static_cast<int>(v.i64(0, 0));
  if (version > latest)
    throw StoreError("PostgreSQL database has schema version " + std::to_string(version) +
                     ", newer than this meshmark knows (" + std::to_string(latest) + "); upgrade meshmark");
  return version;
}

}  // namespace mm::store::pg
