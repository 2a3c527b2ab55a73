#!/usr/bin/env bash
# The fast part of the suite under AddressSanitizer and UndefinedBehaviorSanitizer (build type
# Asan, its own folder build-asan/): the readers of outside bytes, the HTTP server and the store
# (SQLite, and the PostgreSQL layer against a throwaway server), with the fuzz
# targets' regression inputs. Every test binary must pass with no sanitizer report (UBSan halts
# on its first finding). The slow numerical suites (fitting, registration, jobs, end to end) run
# only in the ordinary build: under ASan they would not fit CI's time.
# Usage: scripts/sanitize.sh   (ASAN_BUILD_DIR, JOBS)
set -euo pipefail
cd "$(dirname "$0")/.."
B=${ASAN_BUILD_DIR:-build-asan}
JOBS=${JOBS:-$(nproc)}
TESTS="test_support test_meshio test_cad test_codec test_store test_store_postgres test_http_server test_watermark test_spectral test_subdivision test_geometry"
FUZZ="mesh cad stream config copy_record"
cmake -S . -B "$B" -DCMAKE_BUILD_TYPE=Asan >/dev/null
cmake --build "$B" -j "$JOBS" --target $TESTS $(for f in $FUZZ; do echo "fuzz_$f"; done) >/dev/null
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=suppressions=$PWD/tests/lsan-suppressions.txt  # leaks inside Debian libraries
status=0
for t in $TESTS; do
  bin=$(find "$B/tests" -name "$t" -type f | head -1)
  if (cd "$(dirname "$bin")" && "./$t" --gtest_brief=1 >"$t.log" 2>&1); then
    echo "sanitize $t: $(grep -m1 -o '[0-9]* tests\? from [0-9]* test suites\? ran' "$(dirname "$bin")/$t.log" || echo ok)"
  else
    echo "sanitize $t: FAILED" >&2
    tail -40 "$(dirname "$bin")/$t.log" >&2
    status=1
  fi
done
for f in $FUZZ; do
  if "$B/tests/fuzz/fuzz_$f" "tests/fuzz/regressions/$f" >"$B/fuzz_$f.log" 2>&1; then
    echo "sanitize fuzz_$f: regression inputs replayed"
  else
    echo "sanitize fuzz_$f: FAILED" >&2
    tail -40 "$B/fuzz_$f.log" >&2
    status=1
  fi
done
exit $status
