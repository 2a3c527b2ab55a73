// A fleet on PostgreSQL, end to end through the real binaries: a home whose store is a PostgreSQL
// database (MESHMARK_STORE for the CLI, store.postgres in meshmarkd.json), two nodes working the
// queue at once, every job done once, and a leak traced through the shared store.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>
#include <chrono>
#include <csignal>

#include "common/postgres_server.h"
#include "common/shared_meshes.h"
#include "store/home.h"
#include "store/pg_db.h"
#include "store/pg_store.h"
#include "store/sqlite_db.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

// A throwaway PostgreSQL server with one database, the test's folders (home, drop, out) and the
// CLI run with its output collected in cli.log. The password in the conninfo is ignored (trust
// authentication) and stands for one that must never be shown.
class Fleet : public ::testing::Test {
 protected:
  void SetUp() override {
    MM_REQUIRE_POSTGRES();
    server_ = std::make_unique<mm::test::PostgresServer>();
    mm::store::pg::Connection(server_->conninfo()).exec("CREATE DATABASE fleet");
    conninfo = server_->conninfo("fleet") + " password=" + password;
    dir = fs::temp_directory_path() /
          ("mm-fleet-" + std::to_string(::getpid()) + "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    home = dir / "home";
    drop = dir / "drop";
    out = dir / "out";
    fs::create_directories(drop);
    fs::create_directories(out);
    ::unsetenv("MESHMARK_MASTER_KEY");
    ::unsetenv("MESHMARK_STORE");
  }
  void TearDown() override {
    if (!HasFailure() && !dir.empty()) fs::remove_all(dir);
  }
  int sh(const std::string& cmd) { return std::system((cmd + " >>" + (dir / "cli.log").string() + " 2>&1").c_str()); }
  std::string cli_log() { return slurp(dir / "cli.log"); }
  // meshmarkd.json for this test's folders, with `extra` keys.
  fs::path write_config(const std::string& name, const json& extra) {
    json c{{"home", home.string()}, {"drop_dir", drop.string()}, {"output_dir", out.string()},
           {"workers", 1},          {"poll_interval_ms", 100},   {"output_format", "off"}};
    c.update(extra);
    std::ofstream(dir / name) << c.dump();
    return dir / name;
  }
  // The path of `customer`'s decoded copy in the store.
  fs::path decoded_copy(mm::store::Store& st, const std::string& customer) {
    const auto who = st.find_customer(customer);
    for (const auto& c : st.list_copies()) {
      if (c.customer_id != who->id) continue;
      const json outputs = json::parse(c.outputs_json);  // outlives the loop over its files
      for (const auto& f : outputs["files"])
        if (f["role"] == "decoded") return f["path"].get<std::string>();
    }
    return {};
  }
  std::unique_ptr<mm::store::Store> fleet_store() {
    mm::store::StoreOptions o;
    o.blob_dir = (home / "blobs").string();
    return mm::store::open_postgres_store(conninfo, o);
  }

  const std::string exe = MESHMARK_EXE;
  const std::string password = "s3cret-of-the-fleet";
  std::string conninfo;
  fs::path dir, home, drop, out;

  std::unique_ptr<mm::test::PostgresServer> server_;
};

TEST_F(Fleet, TwoNodesOnOnePostgresDatabaseProtectOnceAndTraceALeak) {
  MM_REQUIRE_SHARED_MESHES();
  const std::string env = "MESHMARK_STORE='" + conninfo + "' ";
  ASSERT_EQ(sh(env + exe + " init --home " + home.string()), 0) << cli_log();
  ASSERT_EQ(sh(env + exe + " customer add alpha --home " + home.string()), 0) << cli_log();
  ASSERT_EQ(sh(env + exe + " customer add beta --home " + home.string()), 0) << cli_log();
  EXPECT_FALSE(fs::exists(home / "meshmark.db")) << "the store is the PostgreSQL database, not a SQLite file";
  const fs::path cfg = write_config("meshmarkd.json", {{"lease_seconds", 30}, {"heartbeat_seconds", 2},
                                                       {"store", {{"postgres", conninfo}}}});
  const std::string part = mm::test::shared_mesh("abc7.stl"), other = mm::test::shared_mesh("chamfer-cube.off");
  for (const char* customer : {"alpha", "beta"})
    for (const std::string& file : {part, other})
      ASSERT_EQ(sh(exe + " submit protect --config " + cfg.string() + " --customer " + customer + " " + file), 0)
          << cli_log();

  // Two nodes work the queue at once.
  const std::string run = exe + " run --until-empty --no-drops --config " + cfg.string();
  ASSERT_EQ(sh("(" + run + " & " + run + " & wait)"), 0) << cli_log();

  auto st = fleet_store();
  const auto jobs = st->list_jobs({});
  ASSERT_EQ(jobs.size(), 4u);
  for (const auto& j : jobs) {
    EXPECT_EQ(j.state, mm::store::JobState::completed) << j.id << " " << j.result_json;
    EXPECT_EQ(j.attempt, 1) << "each job claimed once";
  }
  ASSERT_EQ(st->list_copies().size(), 4u) << "one copy per customer and part, none twice";

  // beta's copy of abc7 leaks; either node traces it through the shared store.
  fs::path leaked;
  const auto beta = st->find_customer("beta");
  for (const auto& c : st->list_copies()) {
    if (c.customer_id != beta->id || st->get_asset(c.asset_id)->name != "abc7.stl") continue;
    const json outputs = json::parse(c.outputs_json);  // outlives the loop over its files
    for (const auto& f : outputs["files"])
      if (f["role"] == "decoded") leaked = f["path"].get<std::string>();
  }
  ASSERT_FALSE(leaked.empty());
  ASSERT_EQ(sh(exe + " submit detect --config " + cfg.string() + " " + leaked.string()), 0) << cli_log();
  ASSERT_EQ(sh(run), 0) << cli_log();
  const auto dets = st->list_detections();
  ASSERT_EQ(dets.size(), 1u);
  EXPECT_EQ(dets[0].verdict, "attributed") << dets[0].details_json.substr(0, 400);
  ASSERT_TRUE(dets[0].customer_id);
  EXPECT_EQ(*dets[0].customer_id, beta->id);
  EXPECT_EQ(cli_log().find(password), std::string::npos) << "the password never reaches the output";
}

// A single machine's SQLite store moved into PostgreSQL (meshmark store migrate --to): the old
// detection is there with its id, and the old leak detected again on the fleet's store gives the
// same verdict and p-value, bit for bit.
TEST_F(Fleet, AStoreMovedFromSqliteIntoPostgresTracesAnOldLeakTheSame) {
  MM_REQUIRE_SHARED_MESHES();
  ASSERT_EQ(sh(exe + " init --home " + home.string()), 0) << cli_log();
  for (const char* customer : {"alpha", "beta"})
    ASSERT_EQ(sh(exe + " customer add " + customer + " --home " + home.string()), 0) << cli_log();
  const fs::path sqlite_cfg = write_config("single.json", json::object());
  const fs::path fleet_cfg = write_config("fleet.json", {{"store", {{"postgres", conninfo}}}});
  const std::string part = mm::test::shared_mesh("abc7.stl");
  for (const char* customer : {"alpha", "beta"})
    ASSERT_EQ(sh(exe + " submit protect --config " + sqlite_cfg.string() + " --customer " + customer + " " + part), 0);
  ASSERT_EQ(sh(exe + " run --until-empty --no-drops --config " + sqlite_cfg.string()), 0) << cli_log();
  auto single = mm::store::open_home(mm::store::resolve_home(home.string()), false);
  const fs::path leaked = decoded_copy(*single, "beta");
  ASSERT_FALSE(leaked.empty());
  ASSERT_EQ(sh(exe + " submit detect --config " + sqlite_cfg.string() + " " + leaked.string()), 0);
  ASSERT_EQ(sh(exe + " run --until-empty --no-drops --config " + sqlite_cfg.string()), 0) << cli_log();
  const auto before = single->list_detections();
  ASSERT_EQ(before.size(), 1u);
  ASSERT_EQ(before[0].verdict, "attributed");
  const auto jobs_before = single->list_jobs({}).size();
  single.reset();

  {
    // A table the move does not know (a later migration's) stops it before anything is written.
    mm::store::sql::Db db((home / "meshmark.db").string(), 1000);
    db.exec("CREATE TABLE later_feature (x INTEGER)", "adding a table");
  }
  EXPECT_NE(sh(exe + " store migrate --to '" + conninfo + "' --home " + home.string()), 0);
  EXPECT_NE(cli_log().find("its table later_feature is not one"), std::string::npos) << cli_log();
  EXPECT_EQ(fleet_store()->list_customers().size(), 0u);
  mm::store::sql::Db((home / "meshmark.db").string(), 1000).exec("DROP TABLE later_feature", "dropping it");
  ASSERT_EQ(sh(exe + " store migrate --to '" + conninfo + "' --home " + home.string()), 0) << cli_log();
  EXPECT_NE(sh(exe + " store migrate --to '" + conninfo + "' --home " + home.string()), 0)
      << "a second move into a database that holds the first is refused";
  // The blobs moved with the rows: the fleet no longer needs the machine's blobs/ folder.
  std::size_t moved_blobs = 0;
  for (const auto& shard : fs::directory_iterator(home / "blobs"))
    if (shard.path().filename() != "tmp") moved_blobs += static_cast<std::size_t>(std::distance(fs::directory_iterator(shard), {}));
  fs::rename(home / "blobs", dir / "blobs-of-the-single-machine");
  auto fleet = fleet_store();
  ASSERT_GT(moved_blobs, 0u);
  for (const auto& a : fleet->list_assets()) EXPECT_TRUE(fleet->blobs().contains(a.sha256)) << a.name;
  EXPECT_EQ(mm::store::pg::Connection(conninfo).exec("SELECT COUNT(*) FROM blobs").i64(0, 0),
            static_cast<std::int64_t>(moved_blobs));
  ASSERT_EQ(fleet->list_detections().size(), 1u);
  EXPECT_EQ(fleet->list_detections()[0].id, before[0].id);
  EXPECT_EQ(fleet->list_copies().size(), 2u);
  EXPECT_EQ(fleet->list_jobs({}).size(), jobs_before);

  // Under another name: the same file and name would be the moved detect job itself (its key).
  const fs::path again = dir / "leak-on-the-fleet.off";
  fs::copy_file(leaked, again);
  ASSERT_EQ(sh(exe + " submit detect --config " + fleet_cfg.string() + " " + again.string()), 0);
  ASSERT_EQ(sh(exe + " run --until-empty --no-drops --config " + fleet_cfg.string()), 0) << cli_log();
  const auto after = fleet->list_detections();
  ASSERT_EQ(after.size(), 2u);
  EXPECT_GT(after[0].id, before[0].id) << "new ids continue after the moved ones";
  EXPECT_EQ(after[0].verdict, before[0].verdict);
  EXPECT_EQ(after[0].customer_id, before[0].customer_id);
  EXPECT_EQ(after[0].copy_id, before[0].copy_id);
  ASSERT_TRUE(after[0].p_value && before[0].p_value);
  EXPECT_EQ(*after[0].p_value, *before[0].p_value) << "the same numbers, bit for bit";
  EXPECT_EQ(cli_log().find(password), std::string::npos);
}

// meshmarkd nodes on one database: one leads; killed, it is replaced within one lease (three
// heartbeats); a node stopped cleanly leaves the fleet. `meshmark fleet status` shows it all.
TEST_F(Fleet, AKilledLeaderIsReplacedWithinOneLease) {
  ASSERT_EQ(sh("MESHMARK_STORE='" + conninfo + "' " + exe + " init --home " + home.string()), 0) << cli_log();
  const fs::path cfg = write_config("meshmarkd.json", {{"heartbeat_seconds", 1}, {"log_level", "info"},
                                                       {"store", {{"postgres", conninfo}}}});
  auto start = [&](const std::string& log) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      const std::string out_file = (dir / log).string();
      FILE* f = std::freopen(out_file.c_str(), "a", stderr);
      (void)f;
      ::execl(MESHMARKD_EXE, MESHMARKD_EXE, "--config", cfg.string().c_str(), static_cast<char*>(nullptr));
      std::_Exit(127);
    }
    return pid;
  };
  auto status = [&] {
    const fs::path j = dir / "status.json";
    std::system((exe + " fleet status --json --config " + cfg.string() + " > " + j.string() + " 2>/dev/null").c_str());
    return json::parse(slurp(j), nullptr, false);
  };
  // The leader's name, once `want` nodes are listed and one other than `not_this` leads (within
  // `seconds`); "" if not.
  auto leader_among = [&](std::size_t want, double seconds, const std::string& not_this = "") {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      const json s = status();
      if (s.is_object() && s["nodes"].size() == want)
        for (const auto& n : s["nodes"])
          if (n["leader"].get<bool>() && n["name"] != not_this) return n["name"].get<std::string>();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return std::string();
  };
  // Whatever happens, no daemon outlives the test.
  std::vector<pid_t> started;
  struct Reaper {
    std::vector<pid_t>& pids;
    ~Reaper() {
      for (pid_t p : pids)
        if (::kill(p, SIGKILL) == 0) ::waitpid(p, nullptr, 0);
    }
  } reaper{started};
  const pid_t a = start("a.log");
  started.push_back(a);
  const std::string first = leader_among(1, 20);
  ASSERT_EQ(first.substr(first.rfind(':') + 1), std::to_string(a)) << slurp(dir / "a.log");
  const pid_t b = start("b.log");
  started.push_back(b);
  EXPECT_EQ(leader_among(2, 20), first) << "the second node does not take the lease while the first holds it";
  ::kill(a, SIGKILL);
  ::waitpid(a, nullptr, 0);
  const auto killed = std::chrono::steady_clock::now();
  const std::string second = leader_among(2, 10, first);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  ASSERT_EQ(second.substr(second.rfind(':') + 1), std::to_string(b)) << slurp(dir / "b.log");
  std::printf("  leader killed: replaced after %.2f s\n", took);
  // Lease 3 s (three heartbeats) and a beat a second: about 3-4 s here. The exact bound is the
  // store's (Queue.OneNodeLeadsUntilItsLeaseRunsOutOrItLeaves, on a stepped clock); this bound
  // leaves room for a loaded machine.
  EXPECT_LT(took, 10) << "replaced after the lease";
  ::kill(b, SIGTERM);
  int st = 0;
  ::waitpid(b, &st, 0);
  EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0) << slurp(dir / "b.log");
  const json after = status();
  ASSERT_EQ(after["nodes"].size(), 1u) << "b left; the killed a stays listed, seen seconds ago";
  EXPECT_EQ(after["nodes"][0]["name"], first);
  EXPECT_FALSE(after["nodes"][0]["leader"].get<bool>());
  EXPECT_NE(slurp(dir / "b.log").find("is now the leader"), std::string::npos) << slurp(dir / "b.log");
}

// An idle node claims a job another process enqueued at once (LISTEN/NOTIFY), not at its next
// poll (20 s here), and again after the database restarted under it.
TEST_F(Fleet, AnIdleNodeWakesOnAnEnqueueAlsoAfterTheDatabaseRestarts) {
  MM_REQUIRE_SHARED_MESHES();
  ASSERT_EQ(sh("MESHMARK_STORE='" + conninfo + "' " + exe + " init --home " + home.string()), 0) << cli_log();
  for (const char* customer : {"alpha", "beta"})
    ASSERT_EQ(sh("MESHMARK_STORE='" + conninfo + "' " + exe + " customer add " + customer + " --home " + home.string()), 0);
  const fs::path cfg = write_config("meshmarkd.json", {{"poll_interval_ms", 20000}, {"log_level", "info"},
                                                       {"store", {{"postgres", conninfo}}}});
  const pid_t pid = ::fork();
  if (pid == 0) {
    FILE* f = std::freopen((dir / "node.log").c_str(), "a", stderr);
    (void)f;
    ::execl(MESHMARKD_EXE, MESHMARKD_EXE, "--config", cfg.string().c_str(), static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  struct Reaper {
    pid_t pid;
    ~Reaper() {
      if (::kill(pid, SIGKILL) == 0) ::waitpid(pid, nullptr, 0);
    }
  } reaper{pid};
  auto wait_for_log = [&](const std::string& line, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (slurp(dir / "node.log").find(line) != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  };
  auto st = fleet_store();
  // Submits a protect job for `customer` and returns the seconds from its enqueue to its claim.
  auto claimed_after = [&](const std::string& customer) {
    EXPECT_EQ(sh(exe + " submit protect --config " + cfg.string() + " --customer " + customer + " " +
                 mm::test::shared_mesh("chamfer-cube.off")),
              0)
        << cli_log();
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    while (std::chrono::steady_clock::now() < end) {
      for (const auto& j : st->list_jobs({}))
        if (j.payload_json.find(customer) != std::string::npos && j.attempted_at)
          return static_cast<double>(*j.attempted_at - j.created_at) / 1000;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return 1e9;
  };
  ASSERT_TRUE(wait_for_log("meshmarkd started", 20)) << slurp(dir / "node.log");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the worker is idle, waiting
  const double first = claimed_after("alpha");
  EXPECT_LT(first, 5) << "woken by the enqueue, not by a poll 20 s later\n" << slurp(dir / "node.log");

  server_->stop();
  server_->start();
  ASSERT_TRUE(wait_for_log("fleet: job wake-ups resumed", 20)) << slurp(dir / "node.log");
  st = fleet_store();  // the test's own connection ended with the server
  const double second = claimed_after("beta");
  EXPECT_LT(second, 5) << "listening again after the restart\n" << slurp(dir / "node.log");
  std::printf("  claimed %.2f s after the enqueue; after a restart of the database %.2f s\n", first, second);
}

}  // namespace
