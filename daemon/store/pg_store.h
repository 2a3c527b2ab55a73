// The store on PostgreSQL, for a fleet of meshmarkd nodes sharing one database (docs/store.md).
// The same Store contract as SQLite, with what several machines need:
//  - claims as PostgreSQL queues make them: the best job's row taken with FOR UPDATE SKIP LOCKED
//    and marked running in the same statement, so nodes claiming together never wait on, or
//    take, one another's job;
//  - time from the database's clock (mm_now_ms()), never a node's; StoreOptions::clock, when set
//    (tests), replaces it;
//  - an enqueue NOTIFYs channel mm_jobs with the job's kind, so idle nodes wake at once
//    (wait_for_jobs); polling remains the fallback.
// One connection per Store object (calls are serialized on it), in session mode: LISTEN and the
// advisory locks do not survive a transaction-mode pooler such as PgBouncer's.
// Blobs live in the database (store/pg_blob_store.h); StoreOptions::blob_dir is this node's cache
// of the blobs it hands to libraries as files (BlobStore::path).
#pragma once
#include <memory>
#include <string>

#include "store/store.h"

namespace mm::store {

// Connects (conninfo "postgresql://..." or "host=... dbname=..."), applies pending migrations
// (schema/postgres/) and checks the master key as open_sqlite_store does. options.db_path is
// ignored; options.blob_dir (the node's blob cache) must be given. StoreError when it cannot connect, naming no password.
std::unique_ptr<Store> open_postgres_store(const std::string& conninfo, StoreOptions options);

// Blocks until a job is enqueued on the database behind `conninfo`'s store (a NOTIFY on mm_jobs)
// or timeout_ms passes; true when woken by one.
class JobWakeups {
 public:
  explicit JobWakeups(const std::string& conninfo);
  ~JobWakeups();
  bool wait(int timeout_ms);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mm::store
