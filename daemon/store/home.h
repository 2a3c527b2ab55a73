// The meshmark home folder: where one installation keeps its database, blobs and master key.
//   <home>/meshmark.db     SQLite store
//   <home>/blobs/          content-addressed files (FsBlobStore)
//   <home>/master.key      master key, mode 0600 (unless MESHMARK_MASTER_KEY is set)
// The home is --home, else $MESHMARK_HOME, else ./meshmark-home. A fleet's nodes keep their store
// in PostgreSQL instead of meshmark.db: store_url (from $MESHMARK_STORE, or the daemon's config key
// store.postgres) names it (blobs included), and each node's home keeps the master key and its blob cache.
#pragma once
#include <memory>
#include <string>

#include "store/store.h"

namespace mm::store {

struct HomePaths {
  std::string root, db, blobs, master_key;
  std::string store_url;  // "" = the SQLite store meshmark.db; else a PostgreSQL conninfo
};

// A conninfo as it may be shown: a password in it (URL or key=value form) replaced by "***".
std::string redacted_conninfo(const std::string& conninfo);

HomePaths resolve_home(const std::string& home_option);  // "" = env or default
// Creates the folder (0700), a master key file if neither it nor MESHMARK_MASTER_KEY exists, and
// the database with all migrations. Returns true if anything was created.
bool init_home(const HomePaths& home);
// Opens the store of an initialized home (StoreError if not initialized). need_master_key loads
// the master key (KeyError if missing or badly protected); without it key operations throw.
std::unique_ptr<Store> open_home(const HomePaths& home, bool need_master_key, StoreOptions base = {});

}  // namespace mm::store
