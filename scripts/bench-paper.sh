#!/usr/bin/env bash
# Reproduces the paper's Table I and Figure 8 on ../shared/data/meshes/fandisk_quads.off and runs
# the spectral benchmark. Results go to $OUT (default build/paper-results): table1.csv,
# figure8.csv, figure8.png, paper_experiments.txt and bench_spectral.txt.
# Usage: scripts/bench-paper.sh [--no-bench]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
OUT=${OUT:-$BUILD_DIR/paper-results}
MESH=${MESH:-../shared/data/meshes/fandisk_quads.off}
if [ ! -f "$MESH" ]; then
  echo "bench-paper: $MESH is absent (clone with ../shared beside this repository)" >&2
  exit 1
fi
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD_DIR" -j "${JOBS:-2}" --target paper_experiments bench_spectral
mkdir -p "$OUT"
"$BUILD_DIR"/tests/watermark/paper_experiments "$OUT" "$MESH" | tee "$OUT/paper_experiments.txt"
if [ "${1:-}" != "--no-bench" ]; then
  "$BUILD_DIR"/tests/spectral/bench_spectral | tee "$OUT/bench_spectral.txt"
fi
