// Eigen-decomposition, embedding and extraction cost on seeded quad-torus control meshes of 100,
// 500 and 2000 vertices (one dense basis) and 10,000 and 50,000 (patched bases). Counters: the
// stored basis's size and the process's peak resident memory so far. Run: bench_spectral
// (Release build).
#include <benchmark/benchmark.h>

#include <sys/resource.h>

#include <random>

#include "spectral/spectral_basis.h"
#include "spectral/synthetic_meshes.h"
#include "watermark/watermark.h"

namespace {

mm::Mesh control_mesh(int n) {
  switch (n) {
    case 100: return mm::test::quad_torus(10, 10, 42);
    case 500: return mm::test::quad_torus(25, 20, 42);
    case 2000: return mm::test::quad_torus(50, 40, 42);
    case 10000: return mm::test::quad_torus(125, 80, 42);
    default: return mm::test::quad_torus(250, 200, 42);
  }
}

void count_memory(benchmark::State& state, const mm::SpectralBasis& basis) {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  state.counters["vertices"] = basis.num_vertices();
  state.counters["patches"] = static_cast<double>(basis.patches.size());
  double bytes = 0;  // the stored form's size, without making it (which would raise the peak)
  for (const mm::SpectralPatch& p : basis.patches)
    bytes += 8.0 * static_cast<double>(p.vertices.size()) * static_cast<double>(p.vertices.size() + 1);
  state.counters["basis_MB"] = bytes / 1e6;
  state.counters["peak_rss_MB"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
}

void BM_ComputeBasis(benchmark::State& state) {
  const mm::Mesh mesh = control_mesh(static_cast<int>(state.range(0)));
  mm::SpectralBasis basis;
  for (auto _ : state) benchmark::DoNotOptimize(basis = mm::compute_basis(mesh));
  count_memory(state, basis);
}

void BM_Embed(benchmark::State& state, mm::Method method) {
  const mm::Mesh mesh = control_mesh(static_cast<int>(state.range(0)));
  const mm::SpectralBasis basis = mm::compute_basis(mesh);
  std::mt19937_64 rng(7);
  std::vector<bool> message(64);
  for (size_t i = 0; i < message.size(); ++i) message[i] = rng() & 1;
  mm::Key key{};
  mm::Nonce nonce{};
  key[0] = 1;
  const mm::EmbedParams params{method, 0.01, 0.05};
  for (auto _ : state) benchmark::DoNotOptimize(mm::embed(basis, mesh.points, message, key, nonce, params));
  count_memory(state, basis);
}

void BM_Extract(benchmark::State& state) {
  const mm::Mesh mesh = control_mesh(static_cast<int>(state.range(0)));
  const mm::SpectralBasis basis = mm::compute_basis(mesh);
  std::vector<bool> message(64, true);
  mm::Key key{};
  mm::Nonce nonce{};
  const mm::EmbedParams params{mm::Method::Additive, 0.01, 0.05};
  const mm::Points marked = mm::embed(basis, mesh.points, message, key, nonce, params);
  for (auto _ : state)
    benchmark::DoNotOptimize(mm::extract(basis, mesh.points, marked, 64, key, nonce, params, &message));
  count_memory(state, basis);
}

}  // namespace

#define MM_SIZES ->Arg(100)->Arg(500)->Arg(2000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMillisecond)
BENCHMARK(BM_ComputeBasis) MM_SIZES;
BENCHMARK_CAPTURE(BM_Embed, method1, mm::Method::Multiplicative) MM_SIZES;
BENCHMARK_CAPTURE(BM_Embed, method2, mm::Method::Additive) MM_SIZES;
BENCHMARK(BM_Extract) MM_SIZES;
BENCHMARK_MAIN();
