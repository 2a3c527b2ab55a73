// Detection speed of one suspect (Google Benchmark; run by scripts/bench-detect-speed.sh on one
// core): rocker.stl protected with the default settings, one copy leaked, the suspect handed over
// in the part's units as the daemon does. Each iteration is what a detect job computes for one
// candidate polyhedron: alignment and resynchronisation (align_suspect, with the asset's
// resynchronisation context already cached, as meshmarkd's context cache keeps it), the surface
// offsets of a surface-fit suspect, and every issued copy scored (score_copies).
//  - arg 0: the decoded copy with noise of 0.1 % of the largest side (in order, "subdivided");
//  - arg 1: the decoded copy remeshed isotropically to about 64k vertices ("surface-fit");
//  - second arg: copies issued for the asset (3, or 1,000: what each further copy costs).
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <random>

#include "attacks/perturb.h"
#include "attacks/retessellate.h"
#include "common/seeded_keys.h"
#include "jobs/detect.h"
#include "jobs/detect_suspect.h"
#include "jobs/payload.h"
#include "jobs/protect.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"

namespace {

using namespace mm;
using namespace mm::jobs;

struct Setup {
  PreparedAsset asset;
  std::vector<CopyCandidate> copies;  // 1,000; copy 1 leaked
  std::map<int, Mesh> suspects;
  std::shared_ptr<const ResyncContext> context;
};

const Setup& setup() {
  static const Setup s = [] {
    Setup x;
    const Mesh part = read_mesh(std::string(MESHMARK_SHARED_MESHES) + "/rocker.stl");
    x.asset = prepare_asset(part, {}, "rocker.stl");
    for (int i = 0; i < 1000; ++i) {
      CopyCandidate c;
      c.copy_id = i + 1;
      c.key = test::key_from(500 + i);
      c.nonce = test::nonce_from(500 + i);
      c.payload = 0x5000u + static_cast<unsigned>(i);
      x.copies.push_back(c);
    }
    const CopyCandidate& leaker = x.copies[1];
    const Mesh decoded =
        make_copy_files(x.asset, make_copy(x.asset, leaker.key, leaker.nonce, leaker.payload, leaker.settings), {},
                        false)
            .decoded;
    x.suspects[0] = decoded;
    attacks::add_uniform_noise(x.suspects[0].points, 0.001, 3);
    x.suspects[1] = attacks::remesh_isotropic(decoded, 0.0045);
    x.context = std::make_shared<const ResyncContext>(make_resync_context(x.asset));
    return x;
  }();
  return s;
}

void BM_DetectOneSuspect(benchmark::State& state) {
  const Setup& s = setup();
  const Mesh& suspect = s.suspects.at(static_cast<int>(state.range(0)));
  const std::vector<CopyCandidate> copies(s.copies.begin(), s.copies.begin() + state.range(1));
  const ContextSource cached = [&s](const std::string&, const std::function<ResyncContext()>&) { return s.context; };
  std::string method;
  double best = 0;
  for (auto _ : state) {
    const Alignment a = align_suspect(s.asset, "rocker", suspect, "suspect", cached);
    std::vector<CopyScore> scores = score_copies(s.asset, a.points, copies, &a.readings);
    for (auto& c : scores) c.corrected_p = corrected_p(c.p_value, static_cast<int>(copies.size()));
    benchmark::DoNotOptimize(scores.data());
    method = a.method;
    best = scores[1].neg_log10_p - std::log10(static_cast<double>(copies.size()));
  }
  state.SetLabel(method + ", " + std::to_string(suspect.num_vertices()) + " vertices");
  state.counters["leaker_neg_log10_corrected_p"] = best;
}
BENCHMARK(BM_DetectOneSuspect)
    ->ArgsProduct({{0, 1}, {3, 1000}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2);

// The two phases of the above apart, for the remeshed suspect: alignment and resynchronisation
// with the surface offsets (align_suspect), then scoring 3 issued copies (score_copies). A first,
// untimed run builds the context's levels, as the daemon's cached context already has them.
void BM_AlignRemeshedSuspect(benchmark::State& state) {
  const Setup& s = setup();
  const ContextSource cached = [&s](const std::string&, const std::function<ResyncContext()>&) { return s.context; };
  align_suspect(s.asset, "rocker", s.suspects.at(1), "suspect", cached);
  for (auto _ : state) {
    const Alignment a = align_suspect(s.asset, "rocker", s.suspects.at(1), "suspect", cached);
    benchmark::DoNotOptimize(a.points.data());
  }
}
BENCHMARK(BM_AlignRemeshedSuspect)->Unit(benchmark::kMillisecond)->MinTime(2);

void BM_ScoreRemeshedSuspect(benchmark::State& state) {
  const Setup& s = setup();
  const ContextSource cached = [&s](const std::string&, const std::function<ResyncContext()>&) { return s.context; };
  const Alignment a = align_suspect(s.asset, "rocker", s.suspects.at(1), "suspect", cached);
  const std::vector<CopyCandidate> copies(s.copies.begin(), s.copies.begin() + 3);
  for (auto _ : state) {
    std::vector<CopyScore> scores = score_copies(s.asset, a.points, copies, &a.readings);
    benchmark::DoNotOptimize(scores.data());
  }
}
BENCHMARK(BM_ScoreRemeshedSuspect)->Unit(benchmark::kMillisecond)->MinTime(2);

}  // namespace

BENCHMARK_MAIN();
