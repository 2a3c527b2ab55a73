#!/usr/bin/env bash
# Reproduces the paper's Table I and Figure 8 on ../shared/data/meshes/fandisk_quads.off and on
# control polyhedra compress() makes from fandisk.off (Figure 8 also with the noise on the decoded,
# subdivided model and detection through registration's resynchronize()), then runs the
# registration benchmark (the spectral one is scripts/bench-spectral.sh). Results go to $OUT (default build/paper-results): per control mesh
# <name>_table1.csv, <name>_figure8.csv/.png, <name>_decoded_figure8.csv/.png, plus
# paper_experiments.txt and bench_registration.txt; the Figure 8 plots are
# copied to docs/results/ and the printed tables written to docs/results/paper.md.
# Usage: scripts/bench-paper.sh [--no-bench]
set -euo pipefail
BENCH_ENV="BUILD_DIR OUT MESH"
. "$(dirname "$0")/bench-results.sh"
bench_results paper "The paper's Table I and Figure 8; registration benchmark" "$@"
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
OUT=${OUT:-$BUILD_DIR/paper-results}
MESH=${MESH:-../shared/data/meshes/fandisk_quads.off}
if [ ! -f "$MESH" ]; then
  echo "bench-paper: $MESH is absent (clone with ../shared beside this repository)" >&2
  exit 1
fi
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD_DIR" -j "${JOBS:-2}" --target paper_experiments bench_registration >&2
mkdir -p "$OUT"
"$BUILD_DIR"/tests/watermark/paper_experiments "$OUT" "$MESH" | tee "$OUT/paper_experiments.txt"
mkdir -p docs/results
! bench_writes_docs || cp "$OUT"/*figure8.png docs/results/
if [ "${1:-}" != "--no-bench" ]; then
  "$BUILD_DIR"/tests/registration/bench_registration | tee "$OUT/bench_registration.txt"
fi
