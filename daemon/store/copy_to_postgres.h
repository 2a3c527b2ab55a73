// Moving a home's SQLite store into PostgreSQL (meshmark store migrate --to ...): every row of
// every table, ids kept, in one PostgreSQL transaction, so a fleet starts with the single
// machine's customers, keys (still sealed under the same master key), assets, copies, detections,
// jobs and audit log, and an old leak gives the same verdict on the fleet.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace mm::store {

struct CopiedTable {
  std::string table;
  std::int64_t rows = 0;
};

// Copies the SQLite database at sqlite_path into the PostgreSQL database `conninfo` (its
// migrations applied first). Refuses (StoreError, nothing written) when the two schema versions
// differ or the PostgreSQL database already holds customers, assets or jobs. The blobs of the
// FsBlobStore at blob_dir move in the same transaction (each verified against its name), reported
// as the table "blobs"; the folder is left as it was.
std::vector<CopiedTable> copy_sqlite_to_postgres(const std::string& sqlite_path, const std::string& blob_dir,
                                                 const std::string& conninfo);

}  // namespace mm::store
