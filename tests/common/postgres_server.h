// A throwaway PostgreSQL server for tests: Debian's postgresql-15 binaries (initdb, pg_ctl) on a
// data folder of its own under the temp folder, listening only on a Unix socket in that folder,
// stopped and removed afterwards. As root it runs as the postgres user (initdb refuses root).
#pragma once
#include <gtest/gtest.h>
#include <pwd.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace mm::test {

inline const char* kPostgresBin = "/usr/lib/postgresql/15/bin";

inline bool postgres_available() { return std::filesystem::exists(std::string(kPostgresBin) + "/initdb"); }

class PostgresServer {
 public:
  // fsync off by default: tests need no durability; a benchmark asks for it.
  explicit PostgresServer(bool fsync = false) : fsync_(fsync) {
    static std::atomic<int> serial{0};
    dir_ = std::filesystem::temp_directory_path() /
           ("mm-pg-" + std::to_string(::getpid()) + "-" + std::to_string(serial++));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    as_ = "";
    if (::geteuid() == 0) {
      const passwd* pw = ::getpwnam("postgres");
      if (!pw) throw std::runtime_error("running as root and there is no postgres user to run PostgreSQL as");
      if (::chown(dir_.c_str(), pw->pw_uid, pw->pw_gid) != 0) throw std::runtime_error("cannot chown " + dir_.string());
      as_ = "runuser -u postgres -- ";
    }
    run(std::string(kPostgresBin) + "/initdb -D " + data() + " -U postgres --auth=trust -E UTF8 --locale=C");
    start();
  }
  ~PostgresServer() {
    stop();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;

  // libpq's connection string for a database of this server.
  std::string conninfo(const std::string& dbname = "postgres") const {
    return "host=" + dir_.string() + " port=5432 user=postgres dbname=" + dbname;
  }
  void start() {
    run(std::string(kPostgresBin) + "/pg_ctl -D " + data() + " -l " + (dir_ / "server.log").string() +
        " -w -o \"-k " + dir_.string() + " -c listen_addresses='' -p 5432 -c fsync=" +
        (fsync_ ? "on" : "off") + "\" start");
    running_ = true;
  }
  // Fast shutdown: the server's sessions are ended, as when it is restarted under load.
  void stop() {
    if (!running_) return;
    std::system((as_ + std::string(kPostgresBin) + "/pg_ctl -D " + data() + " -m fast -w stop >/dev/null 2>&1").c_str());
    running_ = false;
  }
  std::string log() const {
    std::ifstream in(dir_ / "server.log");
    return std::string((std::istreambuf_iterator<char>(in)), {});
  }

 private:
  std::string data() const { return (dir_ / "data").string(); }
  void run(const std::string& cmd) const {
    const std::string out = (dir_ / "command.log").string();
    if (std::system((as_ + cmd + " >" + out + " 2>&1").c_str()) != 0) {
      std::ifstream in(out);
      throw std::runtime_error(cmd + " failed: " + std::string((std::istreambuf_iterator<char>(in)), {}) + log());
    }
  }
  std::filesystem::path dir_;
  std::string as_;
  bool running_ = false;
  bool fsync_ = false;
};

}  // namespace mm::test

// Skips a test when PostgreSQL is not installed, saying so; under CI (CI=true) its absence fails.
#define MM_REQUIRE_POSTGRES()                                                                      \
  do {                                                                                             \
    if (!mm::test::postgres_available()) {                                                         \
      const char* ci = std::getenv("CI");                                                          \
      if (ci && std::string(ci) == "true") FAIL() << "PostgreSQL 15 absent at " << mm::test::kPostgresBin; \
      GTEST_SKIP() << "PostgreSQL 15 absent at " << mm::test::kPostgresBin                         \
                   << ": scripts/install-deps.sh installs postgresql-15";                          \
    }                                                                                              \
  } while (0)
