#!/usr/bin/env bash
# Spectral basis cost: computing the basis, embedding and extracting on seeded quad-torus control
# meshes of 100 to 50,000 vertices (one dense basis up to 6,000, patched past it), with the stored
# basis's size and the peak memory. Writes docs/results/spectral.md.
# Usage: scripts/bench-spectral.sh
set -euo pipefail
BENCH_ENV="BUILD_DIR"
. "$(dirname "$0")/bench-results.sh"
bench_results spectral "Spectral basis: time, stored size and memory by control vertex count" "$@"
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD_DIR" -j "${JOBS:-2}" --target bench_spectral >&2
"$BUILD_DIR"/tests/spectral/bench_spectral
