// meshmarkd throughput and memory (Google Benchmark; run by scripts/bench-daemon.sh):
//  - BM_QueueNoop: no-op jobs per second through the worker pool with 2 workers (claim, run,
//    complete: three SQLite transactions per job, FULL synchronous commits).
//  - BM_EndToEndParts: parts per minute protecting shared CAD meshes for two customers with 2
//    workers, from file to the watermarked .mmc stream + decoded mesh and records, each asset
//    compressed (and its spectral basis computed) once. Arg 0: the four small meshes the e2e test
//    uses (fandisk_quads, chamfer-cube, abc7, abc9); arg 1: the nine CAD parts of
//    docs/compression.md (fandisk, bracket-3, blade, rocker, abc5..abc9, 0.5-7k vertices).
//  - BM_Memory1000: 1,000 protect jobs (abc7 under 1,000 names, one customer); max RSS after 100,
//    500 and 1,000 completed jobs must stay flat.
#include <benchmark/benchmark.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "service/config.h"
#include "service/daemon.h"
#include "service/handlers.h"
#include "service/worker_pool.h"
#include "store/home.h"

namespace {

namespace fs = std::filesystem;
using namespace mm;

struct Env {
  fs::path dir;
  std::shared_ptr<const service::Config> cfg;
  explicit Env(const std::string& tag) {
    dir = fs::temp_directory_path() / ("mm-bench-" + tag + "-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "drop");
    fs::create_directories(dir / "out");
    ::unsetenv("MESHMARK_MASTER_KEY");
    store::init_home(store::resolve_home((dir / "home").string()));
    service::Config c;
    c.home = (dir / "home").string();
    c.drop_dir = (dir / "drop").string();
    c.output_dir = (dir / "out").string();
    c.workers = 2;
    c.poll_interval_ms = 50;
    c.lease_seconds = 300;
    cfg = std::make_shared<const service::Config>(c);
  }
  ~Env() { fs::remove_all(dir); }
  std::unique_ptr<store::Store> open() { return service::open_store(*cfg); }
  // Runs every queued job with 2 workers; calls tick() every 5 ms with the pool's stats.
  double run(const std::function<void(const service::PoolStats&)>& tick = {}) {
    auto c = cfg;
    service::WorkerPool pool(2, [c] { return service::open_store(*c); }, service::default_handlers(),
                             [c] { return c; }, "bench", true);
    auto t0 = std::chrono::steady_clock::now();
    pool.start();
    while (!pool.wait_idle(std::chrono::steady_clock::now() + std::chrono::milliseconds(5)))
      if (tick) tick(pool.stats());
    pool.join();
    if (tick) tick(pool.stats());
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
};

double rss_mb(const char* field) {  // "VmRSS:" or "VmHWM:"
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(field, 0) == 0) return std::stod(line.substr(std::string(field).size())) / 1024.0;
  return 0;
}

std::string shared(const std::string& name) { return std::string(MESHMARK_SHARED_MESHES) + "/" + name; }

void BM_QueueNoop(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  for (auto _ : state) {
    Env env("noop");
    {
      auto st = env.open();
      for (int i = 0; i < n; ++i) {
        store::JobSpec s;
        s.kind = "noop";
        st->enqueue(s, "bench");
      }
    }
    double secs = env.run();
    state.SetIterationTime(secs);
    state.counters["jobs_per_s"] = n / secs;
  }
}
BENCHMARK(BM_QueueNoop)->Arg(2000)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_EndToEndParts(benchmark::State& state) {
  const std::vector<std::string> meshes =
      state.range(0) == 0 ? std::vector<std::string>{"fandisk_quads.off", "chamfer-cube.off", "abc7.stl", "abc9.stl"}
                          : std::vector<std::string>{"fandisk.off", "bracket-3.stl", "blade.stl", "rocker.stl", "abc5.stl",
                                                     "abc6.stl", "abc7.stl", "abc8.stl", "abc9.stl"};
  for (auto _ : state) {
    Env env("parts");
    int parts = 0;
    {
      auto st = env.open();
      for (const char* c : {"alpha", "beta"}) {
        st->add_customer(c, "bench");
        for (const auto& m : meshes) {
          service::submit_protect(*st, c, shared(m), m, 3, "bench");
          ++parts;
        }
      }
    }
    double secs = env.run();
    auto counts = env.open()->counts();
    if (counts.completed != parts) state.SkipWithError("not every part was protected");
    state.SetIterationTime(secs);
    state.counters["parts_per_min"] = parts * 60.0 / secs;
  }
}
BENCHMARK(BM_EndToEndParts)->Arg(0)->Arg(1)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_Memory1000(benchmark::State& state) {
  for (auto _ : state) {
    Env env("mem");
    {
      auto st = env.open();
      st->add_customer("alpha", "bench");
      for (int i = 0; i < 1000; ++i) {
        char name[32];
        std::snprintf(name, sizeof name, "part%04d.stl", i);
        service::submit_protect(*st, "alpha", shared("abc7.stl"), name, 3, "bench");
      }
    }
    double at[3] = {0, 0, 0};
    const std::int64_t marks[3] = {100, 500, 1000};
    double secs = env.run([&](const service::PoolStats& s) {
      for (int k = 0; k < 3; ++k)
        if (at[k] == 0 && s.completed >= marks[k]) at[k] = rss_mb("VmRSS:");
    });
    state.SetIterationTime(secs);
    state.counters["rss_MB_at_100"] = at[0];
    state.counters["rss_MB_at_500"] = at[1];
    state.counters["rss_MB_at_1000"] = at[2];
    state.counters["max_rss_MB"] = rss_mb("VmHWM:");
    state.counters["jobs_per_s"] = 1000 / secs;
    if (env.open()->counts().completed != 1000) state.SkipWithError("not every job completed");
  }
}
BENCHMARK(BM_Memory1000)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::err);  // per-job lines and small-part warnings would swamp the table
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
