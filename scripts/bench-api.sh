#!/usr/bin/env bash
# meshmarkd's HTTP API under load, measured from outside the real daemon (2 workers, 4 HTTP
# threads, loopback): 200 kept-alive clients polling while 1,000 detect jobs run (requests, errors,
# latency p50/p99/max), a 500 MB upload (the daemon's peak RSS before and after) and hostile
# requests interleaved with status requests. Rewrites docs/results/api.md.
# Usage: scripts/bench-api.sh [build-dir]   (default: build)
set -euo pipefail
. "$(dirname "$0")/bench-results.sh"
bench_results api "meshmarkd HTTP API: pollers while jobs run, a 500 MB upload, hostile requests" "$@"
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_api meshmarkd -j2 >&2
"$build/tests/daemon/bench_api" --benchmark_counters_tabular=true
