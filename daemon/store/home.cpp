#include "store/home.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace mm::store {
namespace {
bool exists(const std::string& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0;
}
}  // namespace

HomePaths resolve_home(const std::string& home_option) {
  std::string root = home_option;
  if (root.empty()) {
    const char* env = std::getenv("MESHMARK_HOME");
    root = env && *env ? env : "./meshmark-home";
  }
  while (root.size() > 1 && root.back() == '/') root.pop_back();
  return {root, root + "/meshmark.db", root + "/blobs", root + "/master.key"};
}

bool init_home(const HomePaths& home) {
  bool created = false;
  if (::mkdir(home.root.c_str(), 0700) == 0) {
    created = true;
  } else if (errno != EEXIST) {
    throw StoreError("cannot create home folder " + home.root + ": " + std::strerror(errno));
  }
  if (!keys::master_key_from_env() && !exists(home.master_key)) {
    keys::create_master_key_file(home.master_key);
    created = true;
  }
  bool had_db = exists(home.db);
  StoreOptions o;
  o.db_path = home.db;
  o.blob_dir = home.blobs;
  // With the master key: the store records its check value, so a different key is refused later.
  o.master_key = keys::load_master_key(home.master_key);
  open_sqlite_store(o);  // creates the database and applies migrations
  return created || !had_db;
}

std::unique_ptr<Store> open_home(const HomePaths& home, bool need_master_key, StoreOptions base) {
  if (!exists(home.db))
    throw StoreError("no meshmark store at " + home.root + " (run: meshmark init --home " + home.root + ")");
  base.db_path = home.db;
  base.blob_dir = home.blobs;
  if (need_master_key) base.master_key = keys::load_master_key(home.master_key);
  return open_sqlite_store(std::move(base));
}

}  // namespace mm::store
