#!/usr/bin/env bash
# meshmarkd benchmark: queue throughput (no-op jobs/s), end-to-end parts per minute on the shared
# CAD meshes with 2 workers, and RSS over a 1,000-job run (printed at 100/500/1000 jobs); then the
# store's queue alone (bench_queue: enqueue, claim, complete, with FULL and NORMAL synchronous
# commits, 1 and 2 threads). Rewrites docs/results/daemon.md.
# Usage: scripts/bench-daemon.sh [build-dir]   (default: build)
set -euo pipefail
. "$(dirname "$0")/bench-results.sh"
bench_results daemon "meshmarkd: queue throughput, parts per minute, memory over 1,000 jobs" "$@"
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_daemon bench_queue -j2 >&2
"$build/tests/daemon/bench_daemon" --benchmark_counters_tabular=true
"$build/tests/store/bench_queue" --benchmark_min_time=2 --benchmark_counters_tabular=true
