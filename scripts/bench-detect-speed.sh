#!/usr/bin/env bash
# Detection speed of one suspect on one core (tests/jobs/bench_detect_speed.cpp): rocker.stl's
# decoded copy with noise (in order) and remeshed to about 64k vertices (surface fit), each
# against 3 and 1,000 issued copies; the time includes alignment, resynchronisation and every
# copy's scores, with the asset's resynchronisation context cached as meshmarkd keeps it.
# Rewrites docs/results/detect-speed.md.
# Usage: scripts/bench-detect-speed.sh [build-dir]   (default: build)
set -euo pipefail
. "$(dirname "$0")/bench-results.sh"
bench_results detect-speed "Detection speed of one suspect, one core, 3 and 1,000 copies" "$@"
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_detect_speed -j2 >&2
taskset -c 0 "$build/tests/jobs/bench_detect_speed" --benchmark_counters_tabular=true 2>&1
