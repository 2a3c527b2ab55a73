#!/usr/bin/env bash
# Fuzzes every reader of outside bytes (tests/fuzz: STL/OBJ/OFF/PLY/3MF/GLB/glTF, STEP/IGES, the .mmc
# stream, the config loader, copy records) with libFuzzer under AddressSanitizer and UndefinedBehaviorSanitizer.
# Builds with clang in build-fuzz/ (FUZZ_BUILD_DIR), seeds each corpus from the shared meshes,
# a sample part and its stream, the example config and a copy record that build/'s meshmark
# writes (MESHMARK), and runs each target SECONDS (default 30). A finding is left in
# build-fuzz/findings/<target>/ and the script exits 1: copy it into
# tests/fuzz/regressions/<target>/ with the fix, and ctest replays it from then on.
# Usage: scripts/fuzz.sh [SECONDS]   (TARGETS="mesh cad stream config copy_record", JOBS)
#        scripts/fuzz.sh --ci          CI's short run: a fixed seed and a fixed number of inputs a
#                                      target (about 15 s each on one core), so a run is repeatable.
set -euo pipefail
cd "$(dirname "$0")/.."
CI_MODE=0
if [ "${1:-}" = "--ci" ]; then CI_MODE=1; shift; fi
SECONDS_EACH=${1:-30}
B=${FUZZ_BUILD_DIR:-build-fuzz}
JOBS=${JOBS:-$(nproc)}
TARGETS=${TARGETS:-"mesh cad stream config copy_record"}
MM=$(realpath "${MESHMARK:-build/daemon/meshmark}")
export LSAN_OPTIONS=suppressions=$PWD/tests/lsan-suppressions.txt  # leaks inside Debian libraries
SAN="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
CC=clang CXX=clang++ cmake -S . -B "$B" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMESHMARK_FUZZ=ON \
  -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link $SAN" -DCMAKE_EXE_LINKER_FLAGS="$SAN" >/dev/null
cmake --build "$B" -j "$JOBS" --target fuzzers

# Seed corpora (made once per build folder).
C="$B/corpus"
for t in $TARGETS; do [ -d "$C/$t" ] || rm -f "$C/ready"; done  # a target added since the corpus was made
if [ ! -f "$C/ready" ]; then
  rm -rf "$C" && mkdir -p "$C"/{mesh,cad,stream,config,copy_record}
  seed_mesh() {  # seed_mesh FILE FORMAT_BYTE: the target reads the format from the first byte
    printf "\\x$2" >"$C/mesh/$(basename "$1").$2" && head -c 200000 "$1" >>"$C/mesh/$(basename "$1").$2"
  }
  T=$(mktemp -d)
  "$MM" sample chamfered_block "$T/part.off" >/dev/null
  "$MM" compress --fast "$T/part.off" "$T/part.mmc" >/dev/null
  "$MM" decompress "$T/part.mmc" "$T/part.stl" >/dev/null
  "$MM" decompress "$T/part.mmc" "$T/part.obj" >/dev/null
  "$MM" decompress "$T/part.mmc" "$T/part.ply" >/dev/null
  "$MM" decompress "$T/part.mmc" "$T/part.3mf" >/dev/null
  "$MM" decompress "$T/part.mmc" "$T/part.glb" >/dev/null
  "$MM" decompress "$T/part.mmc" "$T/part.gltf" >/dev/null
  "$MM" sample drilled_block "$T/part.step" >/dev/null
  "$MM" sample drilled_block "$T/part.igs" >/dev/null
  "$MM" keygen "$T/k.key" >/dev/null
  "$MM" embed -m fuzz "$T/part.mmc" "$T/k.key" "$T/copy.mmc" >/dev/null
  seed_mesh "$T/part.stl" 00; seed_mesh "$T/part.obj" 01; seed_mesh "$T/part.off" 02; seed_mesh "$T/part.ply" 03; seed_mesh "$T/part.3mf" 04
  seed_mesh "$T/part.glb" 05; seed_mesh "$T/part.gltf" 06
  for f in ../shared/data/meshes/*.{stl,off,obj,ply}; do
    [ -f "$f" ] || continue
    case "${f##*.}" in stl) seed_mesh "$f" 00 ;; obj) seed_mesh "$f" 01 ;; off) seed_mesh "$f" 02 ;; ply) seed_mesh "$f" 03 ;; esac
  done
  printf '\x00' >"$C/cad/part.step" && cat "$T/part.step" >>"$C/cad/part.step"
  printf '\x01' >"$C/cad/part.igs" && cat "$T/part.igs" >>"$C/cad/part.igs"
  cp "$T/part.mmc" "$C/stream/"
  cp config/meshmark.example.json "$C/config/"
  cp "$T/copy.mmc.mmrec.json" "$C/copy_record/"
  rm -rf "$T"
  touch "$C/ready"
fi

status=0
for t in $TARGETS; do
  mkdir -p "$B/findings/$t" "$B/work/$t"
  cp -n tests/fuzz/regressions/$t/* "$B/work/$t/" 2>/dev/null || true
  # Each run grows its own work corpus from the seeds; -rss_limit_mb bounds what one input may allocate.
  if [ $CI_MODE = 1 ]; then
    rm -rf "$B/work/$t" && mkdir -p "$B/work/$t" && cp tests/fuzz/regressions/$t/* "$B/work/$t/"
    case $t in mesh) runs=10000 ;; cad) runs=2000 ;; *) runs=100000 ;; esac
    limit=(-seed=1 -runs=$runs)
  else
    limit=(-max_total_time="$SECONDS_EACH")
  fi
  if ! "$B/tests/fuzz/fuzz_$t" "$B/work/$t" "$C/$t" "${limit[@]}" -timeout=10 -rss_limit_mb=2048 \
      -artifact_prefix="$B/findings/$t/" -print_final_stats=1 >"$B/findings/$t.log" 2>&1; then
    echo "fuzz $t: FINDING (see $B/findings/$t/ and $B/findings/$t.log)" >&2
    tail -30 "$B/findings/$t.log" >&2
    status=1
  fi
  echo "fuzz $t: $(grep -o 'stat::number_of_executed_units: [0-9]*' "$B/findings/$t.log" | tail -1 | awk '{print $2}') executions in $(grep -m1 -o 'Done [0-9]* runs in [0-9]* second' "$B/findings/$t.log" | awk '{print $5}') s"
done
exit $status
