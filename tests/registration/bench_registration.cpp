// Cost of resynchronisation on fandisk_quads.off (766-vertex control polyhedron, unit box):
// building the per-asset context (levels 0..3) and resynchronising each kind of suspect. Run:
// bench_registration [--benchmark_filter=...] (Release build, shared meshes beside the repo).
#include <benchmark/benchmark.h>

#include <malloc.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "common/shuffled_mesh.h"
#include "fitting/sharp_features.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "registration/remesh.h"
#include "registration/resynchronize.h"
#include "subdivision/subdivide.h"

namespace {

using namespace mm;
using mm::test::shuffled;

const Mesh& control() {
  static const Mesh m = [] {
    Mesh c = read_mesh(std::string(MESHMARK_SHARED_MESHES) + "/fandisk_quads.off");
    apply(unit_box_normalization(c.points), c.points);
    return c;
  }();
  return m;
}

// Built in full up front, so the suspects' timings never include a level's first build.
const ResyncContext& context() {
  static const ResyncContext ctx = [] {
    ResyncContext c(control(), 3);
    c.build_all();
    return c;
  }();
  return ctx;
}

// A context with every level 0..levels and the fit surface built (levels are lazy otherwise).
ResyncContext full_context(const Mesh& control, int levels) {
  ResyncContext ctx(control, levels);
  ctx.build_all();
  return ctx;
}

// Heap in use while one full context of `levels` is alive, in MB (glibc's count; the rest of
// the process, meshes and the static contexts, subtracted), and the context's own estimate.
void context_heap_mb(benchmark::State& state, const Mesh& control, int levels) {
  const double before = static_cast<double>(mallinfo2().uordblks);
  const ResyncContext ctx = full_context(control, levels);
  state.counters["heap_MB"] = (static_cast<double>(mallinfo2().uordblks) - before) / 1e6;
  state.counters["memory_bytes_MB"] = static_cast<double>(ctx.memory_bytes()) / 1e6;
}

void BM_Context(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(full_context(control(), static_cast<int>(state.range(0))));
  state.counters["control_vertices"] = control().num_vertices();
  context_heap_mb(state, control(), static_cast<int>(state.range(0)));
}

// The same polyhedron with its sharp edges tagged, as compress() makes them: the context then
// also factorises the re-subdivided hypothesis (level L-1, then one untagged step) per level.
const Mesh& creased_control() {
  static const Mesh m = [] {
    Mesh c = control();
    const Features f = detect_features(c);
    c.creases = f.sharp_edges;
    c.corners = f.corners;
    return c;
  }();
  return m;
}

void BM_ContextCreased(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(full_context(creased_control(), static_cast<int>(state.range(0))));
  state.counters["creases"] = static_cast<double>(creased_control().creases.size());
  context_heap_mb(state, creased_control(), static_cast<int>(state.range(0)));
}

void run(benchmark::State& state, const Mesh& suspect, const ResyncContext& ctx = context()) {
  std::string method;
  for (auto _ : state) method = resynchronize(ctx, suspect).method;
  state.SetLabel(method);
  state.counters["suspect_vertices"] = suspect.num_vertices();
}

void BM_Polyhedron(benchmark::State& state) { run(state, control()); }

void BM_SubdividedInOrder(benchmark::State& state) {
  run(state, subdivide(control(), static_cast<int>(state.range(0))));
}

void BM_SubdividedShuffled(benchmark::State& state) {
  Mesh s = shuffled(subdivide(control(), static_cast<int>(state.range(0))), 3);
  s.points *= 25.4;  // part units
  run(state, s);
}

void BM_SurfaceFitDecimated(benchmark::State& state) {
  run(state, test::decimate(subdivide(control(), 3), static_cast<int>(state.range(0))));
}

// A decoded level-2 file (no tags) subdivided once more: in its own numbering, and shuffled.
void BM_Resubdivided(benchmark::State& state) {
  static const ResyncContext ctx = full_context(creased_control(), 3);
  Mesh decoded = subdivide(creased_control(), 2);
  decoded.creases.clear();
  decoded.corners.clear();
  Mesh s = subdivide(decoded, 1);
  if (state.range(0) != 0) s = shuffled(s, 3);
  run(state, s, ctx);
  state.counters["shuffled"] = static_cast<double>(state.range(0));
}

}  // namespace

BENCHMARK(BM_Context)->Arg(3)->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ContextCreased)->Arg(3)->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Resubdivided)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Polyhedron)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SubdividedInOrder)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SubdividedShuffled)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SurfaceFitDecimated)->Arg(15000)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
