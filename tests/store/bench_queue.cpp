// Queue throughput: a no-op job enqueued, claimed and completed (three transactions), per second.
// Threads each open their own Store on one shared database (the daemon's worker pool does the
// same). Arg 1: synchronous=FULL (the default, every commit fsynced); 0: NORMAL, for comparison.
#include <benchmark/benchmark.h>
#include <stdlib.h>

#include <filesystem>
#include <mutex>

#include "store/store.h"

namespace {

std::string bench_dir() {
  static std::string dir = [] {
    char tmpl[] = "/tmp/mm-bench-queue-XXXXXX";
    std::string d = ::mkdtemp(tmpl);
    std::atexit([] { std::filesystem::remove_all(bench_dir()); });
    return d;
  }();
  return dir;
}

void BM_NoopJob(benchmark::State& state) {
  mm::store::StoreOptions o;
  o.db_path = bench_dir() + "/queue-" + std::to_string(state.range(0)) + ".db";
  o.synchronous_full = state.range(0) != 0;
  auto s = mm::store::open_sqlite_store(o);
  std::string worker = "bench-" + std::to_string(state.thread_index());
  mm::store::JobSpec spec;
  spec.kind = "noop";
  std::int64_t done = 0;
  for (auto _ : state) {
    s->enqueue(spec, worker);
    auto j = s->claim(worker, 60'000);
    if (!j) {
      state.SkipWithError("claim returned nothing");
      break;
    }
    s->complete(j->id, worker, {});
    ++done;
  }
  state.SetItemsProcessed(done);
}
BENCHMARK(BM_NoopJob)->Arg(1)->Arg(0)->Threads(1)->Threads(2)->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
