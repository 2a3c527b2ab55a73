#include "store/home.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <regex>

#include "store/pg_store.h"

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
  const char* store = std::getenv("MESHMARK_STORE");
  return {root, root + "/meshmark.db", root + "/blobs", root + "/master.key", store ? store : ""};
}

std::string redacted_conninfo(const std::string& conninfo) {
  // postgresql://user:secret@host/db -> postgresql://user:***@host/db
  static const std::regex url("^(postgres(?:ql)?://[^:/@]*:)[^@]*@");
  // password=secret or password = 'sec ret' -> password=***
  static const std::regex keyword("(password\\s*=\\s*)('(?:[^'\\\\]|\\\\.)*'|[^\\s]*)");
  return std::regex_replace(std::regex_replace(conninfo, url, "$1***@"), keyword, "$1***");
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
  if (!home.store_url.empty()) {
    open_postgres_store(home.store_url, o);  // applies the migrations
    return created;
  }
  open_sqlite_store(o);  // creates the database and applies migrations
  return created || !had_db;
}

std::unique_ptr<Store> open_home(const HomePaths& home, bool need_master_key, StoreOptions base) {
  if (!home.store_url.empty()) {
    if (!exists(home.root))
      throw StoreError("no meshmark home at " + home.root + " (run: meshmark init --home " + home.root + ")");
    base.blob_dir = home.blobs;
    if (need_master_key) base.master_key = keys::load_master_key(home.master_key);
    return open_postgres_store(home.store_url, std::move(base));
  }
  if (!exists(home.db))
    throw StoreError("no meshmark store at " + home.root + " (run: meshmark init --home " + home.root + ")");
  base.db_path = home.db;
  base.blob_dir = home.blobs;
  if (need_master_key) base.master_key = keys::load_master_key(home.master_key);
  return open_sqlite_store(std::move(base));
}

}  // namespace mm::store
