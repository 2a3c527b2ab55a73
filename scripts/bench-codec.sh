#!/usr/bin/env bash
# Google Benchmark programs of the compression chain: subdivision (applying and building the
# level-3 operator, decompressing from scratch), the stream coder (encode, decode, decode to level 3)
# and compress() on shared parts. Rewrites docs/results/codec.md.
# Usage: scripts/bench-codec.sh [build-dir]   (default: build; MIN_TIME=0.5 seconds per benchmark)
set -euo pipefail
BENCH_ENV="MIN_TIME"
. "$(dirname "$0")/bench-results.sh"
bench_results codec "Subdivision, stream coder and compress() micro-benchmarks" "$@"
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_subdivision bench_codec bench_compress -j "${JOBS:-2}" >&2
for program in subdivision/bench_subdivision codec/bench_codec fitting/bench_compress; do
  echo "== $program"
  "$build/tests/$program" --benchmark_min_time="${MIN_TIME:-0.5}" 2>/dev/null
done
