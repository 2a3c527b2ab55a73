// Eigen-decomposition and embedding cost on seeded quad-torus control meshes of 100, 500 and
// 2000 vertices. Run: bench_spectral (Release build).
#include <benchmark/benchmark.h>

#include <random>

#include "spectral/spectral_basis.h"
#include "spectral/synthetic_meshes.h"
#include "watermark/watermark.h"

namespace {

mm::Mesh control_mesh(int n) {
  switch (n) {
    case 100: return mm::test::quad_torus(10, 10, 42);
    case 500: return mm::test::quad_torus(25, 20, 42);
    default: return mm::test::quad_torus(50, 40, 42);
  }
}

void BM_ComputeBasis(benchmark::State& state) {
  const mm::Mesh mesh = control_mesh(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(mm::compute_basis(mesh));
  state.counters["vertices"] = mesh.num_vertices();
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
  state.counters["vertices"] = mesh.num_vertices();
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
}

}  // namespace

BENCHMARK(BM_ComputeBasis)->Arg(100)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Embed, method1, mm::Method::Multiplicative)
    ->Arg(100)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Embed, method2, mm::Method::Additive)
    ->Arg(100)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Extract)->Arg(100)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
