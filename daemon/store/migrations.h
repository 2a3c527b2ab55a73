// Schema migrations embedded into the binary at build time from schema/NNNN_name.sql (generated
// and schema/postgres/NNNN_name.sql by daemon/store/embed_schema.cmake), so an installed meshmark
// needs no schema folder.
#pragma once
#include <vector>

namespace mm::store {

struct Migration {
  int version;       // NNNN from the file name; strictly increasing
  const char* name;  // file name
  const char* sql;
};

const std::vector<Migration>& embedded_migrations();  // sorted by version
// schema/postgres/NNNN_name.sql: the same migrations in PostgreSQL's dialect (the same versions).
const std::vector<Migration>& embedded_postgres_migrations();

}  // namespace mm::store
