// Queue throughput: a no-op job enqueued, claimed and completed (three transactions), per second.
// Threads each open their own Store on one shared database (the daemon's worker pool does the
// same). SQLite: arg 1 synchronous=FULL (the default, every commit fsynced); 0: NORMAL, for
// comparison. PostgreSQL: a throwaway local server (Unix socket, fsync on), when installed.
#include <benchmark/benchmark.h>
#include <stdlib.h>

#include <filesystem>
#include <mutex>

#include "common/postgres_server.h"
#include "store/pg_db.h"
#include "store/pg_store.h"
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

// Each iteration: a no-op job enqueued, claimed and completed by this thread's worker.
void run_noop_jobs(benchmark::State& state, mm::store::Store& s) {
  std::string worker = "bench-" + std::to_string(state.thread_index());
  mm::store::JobSpec spec;
  spec.kind = "noop";
  std::int64_t done = 0;
  for (auto _ : state) {
    s.enqueue(spec, worker);
    auto j = s.claim(worker, 60'000);
    if (!j) {
      state.SkipWithError("claim returned nothing");
      break;
    }
    s.complete(j->id, worker, {});
    ++done;
  }
  state.SetItemsProcessed(done);
}

void BM_NoopJob(benchmark::State& state) {
  mm::store::StoreOptions o;
  o.db_path = bench_dir() + "/queue-" + std::to_string(state.range(0)) + ".db";
  o.synchronous_full = state.range(0) != 0;
  auto s = mm::store::open_sqlite_store(o);
  run_noop_jobs(state, *s);
}
BENCHMARK(BM_NoopJob)->Arg(1)->Arg(0)->Threads(1)->Threads(2)->UseRealTime()->Unit(benchmark::kMicrosecond);

// One server for the process; its database made once.
mm::test::PostgresServer* postgres() {
  static std::unique_ptr<mm::test::PostgresServer> server = [] {
    auto s = std::make_unique<mm::test::PostgresServer>(/*fsync=*/true);
    mm::store::pg::Connection(s->conninfo()).exec("CREATE DATABASE queue");
    return s;
  }();
  return server.get();
}

void BM_NoopJobPostgres(benchmark::State& state) {
  if (!mm::test::postgres_available()) {
    state.SkipWithError("PostgreSQL 15 is not installed");
    return;
  }
  static std::mutex m;
  std::unique_ptr<mm::store::Store> s;
  {
    std::lock_guard<std::mutex> l(m);  // one thread applies the migrations at a time
    mm::store::StoreOptions o;
    o.blob_dir = bench_dir() + "/pg-blobs";
    s = mm::store::open_postgres_store(postgres()->conninfo("queue"), o);
  }
  run_noop_jobs(state, *s);
}
BENCHMARK(BM_NoopJobPostgres)->Threads(1)->Threads(2)->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
