#!/usr/bin/env bash
# meshmarkd benchmark: queue throughput (no-op jobs/s), end-to-end parts per minute on the shared
# CAD meshes with 2 workers, and RSS over a 1,000-job run (printed at 100/500/1000 jobs).
# Usage: scripts/bench-daemon.sh [build-dir]   (default: build)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_daemon -j2
exec "$build/tests/daemon/bench_daemon" --benchmark_counters_tabular=true
