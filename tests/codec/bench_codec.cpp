// Encode/decode speed of the .mmc stream on fandisk_quads (766 vertices, 764 faces).
#include <benchmark/benchmark.h>

#include <filesystem>

#include "codec/stream.h"
#include "meshio/read_mesh.h"

namespace {

const mm::Mesh& fandisk() {
  static const mm::Mesh m = [] {
    mm::Mesh mesh = mm::read_mesh(std::string(MESHMARK_SHARED_MESHES) + "/fandisk_quads.off");
    const auto edges = mm::unique_edges(mesh);
    for (size_t e = 0; e < edges.size(); e += 7) mesh.creases.push_back(edges[e]);
    return mesh;
  }();
  return m;
}

void BM_Encode(benchmark::State& state) {
  mm::CodecParams p;
  p.quant_bits = static_cast<int>(state.range(0));
  size_t bytes = 0;
  for (auto _ : state) {
    auto s = mm::encode(fandisk(), p);
    bytes = s.size();
    benchmark::DoNotOptimize(s.data());
  }
  state.counters["stream_bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_Encode)->Arg(12)->Arg(16)->Unit(benchmark::kMillisecond);

void BM_Decode(benchmark::State& state) {
  mm::CodecParams p;
  p.quant_bits = static_cast<int>(state.range(0));
  const auto s = mm::encode(fandisk(), p);
  for (auto _ : state) {
    auto d = mm::decode(s, "bench");
    benchmark::DoNotOptimize(d.mesh.points.data());
  }
  state.counters["stream_bytes"] = static_cast<double>(s.size());
}
BENCHMARK(BM_Decode)->Arg(12)->Arg(16)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
