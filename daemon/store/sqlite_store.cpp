// SQLite implementation of the Store. Every public method takes the object's mutex and, when it
// changes anything, runs in one BEGIN IMMEDIATE transaction: the write lock is taken up front, so
// two connections never both read "available" and then both write "running".
#include <sodium.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>

#include "store/sqlite_store_impl.h"

namespace mm::store {

Millis system_clock_millis() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string iso_utc(Millis ms) {
  std::time_t t = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

const char* to_string(JobState s) {
  switch (s) {
    case JobState::available: return "available";
    case JobState::running: return "running";
    case JobState::completed: return "completed";
    case JobState::retryable: return "retryable";
    case JobState::discarded: return "discarded";
    case JobState::cancelled: return "cancelled";
  }
  return "?";
}

JobState job_state_from_string(const std::string& s) {
  for (JobState j : {JobState::available, JobState::running, JobState::completed,
                     JobState::retryable, JobState::discarded, JobState::cancelled})
    if (s == to_string(j)) return j;
  throw StoreError("unknown job state '" + s.substr(0, 40) + "'");
}

const char* to_string(TokenRole r) {
  switch (r) {
    case TokenRole::read: return "read";
    case TokenRole::submit: return "submit";
    case TokenRole::admin: return "admin";
  }
  return "?";
}

TokenRole token_role_from_string(const std::string& s) {
  for (TokenRole r : {TokenRole::read, TokenRole::submit, TokenRole::admin})
    if (s == to_string(r)) return r;
  throw StoreError("unknown token role '" + s.substr(0, 40) + "' (read, submit or admin)");
}

bool job_transition_allowed(JobState from, JobState to) {
  using S = JobState;
  switch (from) {
    case S::available: return to == S::running || to == S::cancelled;
    case S::retryable: return to == S::running || to == S::available || to == S::cancelled;
    case S::running:
      return to == S::completed || to == S::retryable || to == S::discarded || to == S::available ||
             to == S::cancelled;
    case S::discarded:
    case S::cancelled: return to == S::available;
    case S::completed: return false;
  }
  return false;
}


std::unique_ptr<Store> open_sqlite_store(StoreOptions options) {
  if (options.db_path.empty()) throw StoreError("open store: no database path given");
  return std::make_unique<sqlite_detail::SqliteStore>(std::move(options));
}

}  // namespace mm::store
