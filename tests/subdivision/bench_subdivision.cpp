// Decompression speed: "decompress to level 3 in under 10 ms". Measures applying a prebuilt
// operator (composed S, and step by step), decompressing from scratch (subdivide: topology and
// points level by level) and building the full operator with composed S from scratch, on
// fandisk_quads.off (766 vertices) and a ~100-vertex mixed control mesh.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "meshio/read_mesh.h"
#include "subdivision/subdivide.h"

namespace {

mm::Mesh fandisk() {
  static const mm::Mesh m = [] {
    mm::Mesh r = mm::read_mesh(std::string(MESHMARK_SHARED_MESHES) + "/fandisk_quads.off");
    return r;
  }();
  return m;
}

// ~100-vertex mixed control mesh: the chamfer cube (quads + triangles) after one step.
mm::Mesh small_mixed() {
  static const mm::Mesh m = mm::subdivide(mm::read_mesh(std::string(MESHMARK_SHARED_MESHES) + "/chamfer-cube.off"), 1);
  return m;
}

template <mm::Mesh (*Get)()>
void BM_ApplyComposedS(benchmark::State& state) {
  const mm::Mesh m = Get();
  const mm::SubdivisionOperator op = mm::build_subdivision(m, 3);
  for (auto _ : state) {
    mm::Points p = op.S * m.points;
    benchmark::DoNotOptimize(p.data());
  }
  state.counters["control_v"] = m.num_vertices();
  state.counters["refined_v"] = static_cast<double>(op.S.rows());
  state.counters["nnz_S"] = static_cast<double>(op.S.nonZeros());
}

template <mm::Mesh (*Get)()>
void BM_ApplySteps(benchmark::State& state) {
  const mm::Mesh m = Get();
  const mm::SubdivisionOperator op = mm::build_subdivision(m, 3);
  for (auto _ : state) {
    mm::Points p = mm::apply_subdivision(op, m.points);
    benchmark::DoNotOptimize(p.data());
  }
  state.counters["refined_v"] = static_cast<double>(op.S.rows());
}

template <mm::Mesh (*Get)()>
void BM_BuildAndApplyFromScratch(benchmark::State& state) {
  const mm::Mesh m = Get();
  for (auto _ : state) {
    mm::SubdivisionOperator op = mm::build_subdivision(m, 3);
    benchmark::DoNotOptimize(op.refined.points.data());
  }
}

// Decompression from scratch: refine the topology and the points level by level (no composed S).
template <mm::Mesh (*Get)()>
void BM_SubdivideFromScratch(benchmark::State& state) {
  const mm::Mesh m = Get();
  for (auto _ : state) {
    mm::Mesh r = mm::subdivide(m, 3);
    benchmark::DoNotOptimize(r.points.data());
  }
}

BENCHMARK_TEMPLATE(BM_ApplyComposedS, fandisk)->Name("ApplyComposedS/fandisk_quads/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_ApplySteps, fandisk)->Name("ApplySteps/fandisk_quads/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_SubdivideFromScratch, fandisk)->Name("SubdivideFromScratch/fandisk_quads/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_BuildAndApplyFromScratch, fandisk)->Name("BuildOperatorFromScratch/fandisk_quads/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_ApplyComposedS, small_mixed)->Name("ApplyComposedS/mixed90/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_ApplySteps, small_mixed)->Name("ApplySteps/mixed90/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_SubdivideFromScratch, small_mixed)->Name("SubdivideFromScratch/mixed90/level3")->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_BuildAndApplyFromScratch, small_mixed)->Name("BuildOperatorFromScratch/mixed90/level3")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
