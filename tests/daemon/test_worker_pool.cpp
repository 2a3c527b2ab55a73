// Cancelling a running job stops it: checked between steps, and a job cancelled between its last
// step and its completion has the files it wrote removed; nothing is issued either way.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "service/worker_pool.h"
#include "store/store.h"

namespace {

namespace fs = std::filesystem;
using namespace mm;
using namespace std::chrono_literals;

struct PoolTest : ::testing::Test {
  fs::path dir;
  store::StoreOptions options;
  void SetUp() override {
    dir = fs::temp_directory_path() / ("mm-pool-" + std::to_string(::getpid()) + "-" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
    options.db_path = (dir / "q.db").string();
  }
  void TearDown() override { fs::remove_all(dir); }
  std::unique_ptr<store::Store> open() { return store::open_sqlite_store(options); }

  // Runs one job of kind "slow" through a one-worker pool with `handler`; the test thread cancels
  // it once the handler signals `started`, then lets the handler go on.
  service::PoolStats run_and_cancel(const service::Handler& handler, std::atomic<bool>& started,
                                    std::atomic<bool>& go_on, std::int64_t* job_id) {
    auto st = open();
    store::JobSpec spec;
    spec.kind = "slow";
    *job_id = st->enqueue(spec).job.id;
    auto cfg = std::make_shared<service::Config>();
    service::WorkerPool pool(1, [this] { return open(); }, {{"slow", handler}}, [cfg] { return cfg; }, "test", true);
    pool.start();
    for (int i = 0; i < 500 && !started; ++i) std::this_thread::sleep_for(10ms);
    EXPECT_TRUE(started);
    EXPECT_TRUE(st->cancel(*job_id, "test"));
    go_on = true;
    EXPECT_TRUE(pool.wait_idle(std::chrono::steady_clock::now() + 30s));
    pool.join();
    return pool.stats();
  }
};

TEST_F(PoolTest, CancelledBetweenStepsWritesNothing) {
  std::atomic<bool> started{false}, go_on{false};
  const fs::path out = dir / "copy.stl";
  service::Handler h = [&](store::Store&, const store::Job&, const service::HandlerContext& ctx) {
    started = true;
    while (!go_on) std::this_thread::sleep_for(5ms);
    ctx.check_cancelled();  // as run_protect does before writing its outputs
    std::ofstream(out) << "written";
    return store::JobRecords{};
  };
  std::int64_t id = 0;
  const auto stats = run_and_cancel(h, started, go_on, &id);
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(stats.cancelled, 1);
  EXPECT_EQ(stats.completed + stats.failed + stats.discarded + stats.lease_lost, 0);
  EXPECT_EQ(open()->get_job(id)->state, store::JobState::cancelled);
}

TEST_F(PoolTest, CancelledBeforeCompletionRemovesWhatItWrote) {
  std::atomic<bool> started{false}, go_on{false};
  const fs::path a = dir / "copy.mmc", b = dir / "copy.stl";
  service::Handler h = [&](store::Store&, const store::Job&, const service::HandlerContext&) {
    std::ofstream(a) << "stream";
    std::ofstream(b) << "mesh";
    started = true;
    while (!go_on) std::this_thread::sleep_for(5ms);
    store::JobRecords r;
    store::NewCopy c;
    c.outputs_json = nlohmann::json{{"files", {{{"path", a.string()}}, {{"path", b.string()}}}}}.dump();
    r.copies.push_back(c);
    return r;
  };
  std::int64_t id = 0;
  const auto stats = run_and_cancel(h, started, go_on, &id);
  EXPECT_FALSE(fs::exists(a));
  EXPECT_FALSE(fs::exists(b));
  EXPECT_EQ(stats.cancelled, 1);
  auto st = open();
  EXPECT_EQ(st->get_job(id)->state, store::JobState::cancelled);
  EXPECT_TRUE(st->list_copies().empty());
}

}  // namespace
