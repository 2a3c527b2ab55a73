// Schema migrations embedded into the binary at build time from schema/NNNN_name.sql (generated
// by daemon/store/embed_schema.cmake), so an installed meshmark needs no schema folder.
#pragma once
#include <vector>

namespace mm::store {

struct Migration {
  int version;       // NNNN from the file name; strictly increasing
  const char* name;  // file name
  const char* sql;
};

const std::vector<Migration>& embedded_migrations();  // sorted by version

}  // namespace mm::store
