#!/usr/bin/env bash
# Queue under load: JOBS_N no-op jobs (default 10,000) inserted by another program as the queue
# contract allows, drained by meshmarkd with WORKERS workers (default 4) while a reader runs
# `meshmark jobs list` and `meshmark copies` in a loop. Reports the daemon's throughput, its peak
# memory, and every CLI call that failed (a "database is locked" reaching a user is a failure).
# Writes docs/results/queue-load.md.
# Usage: scripts/bench-queue-load.sh   (JOBS_N, WORKERS, MESHMARK)
set -euo pipefail
cd "$(dirname "$0")/.."
N=${JOBS_N:-10000}
W=${WORKERS:-4}
MM=$(realpath "${MESHMARK:-build/daemon/meshmark}")
MMD=$(realpath "${MESHMARKD:-$(dirname "$MM")/service/meshmarkd}")
T=$(mktemp -d /tmp/meshmark-load.XXXXXX)
pid=""
reader=""
cleanup() {
  [ -n "$reader" ] && kill "$reader" 2>/dev/null
  [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null
  rm -rf "$T"
}
trap cleanup EXIT
mkdir -p "$T"/{drop,out}
"$MM" init --home "$T/home" >/dev/null
cat >"$T/config.json" <<EOF
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": $W, "poll_interval_ms": 100,
 "evidence": {"auto": false}, "log_level": "warn"}
EOF
sqlite3 "$T/home/meshmark.db" "PRAGMA busy_timeout = 10000; PRAGMA wal_autocheckpoint = 0;
  WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < $N)
  INSERT INTO jobs (kind, payload_json, idempotency_key) SELECT 'noop', '{}', 'load:' || i FROM n;" >/dev/null
left() { sqlite3 -cmd ".timeout 10000" "$T/home/meshmark.db" "SELECT COUNT(*) FROM jobs WHERE state <> 'completed'"; }

# The reader: what an operator's status checks do meanwhile.
(
  calls=0 failed=0
  while :; do
    for cmd in "jobs list --limit 20" "jobs list --state available --limit 5" "copies --limit 5"; do
      calls=$((calls + 1))
      # shellcheck disable=SC2086
      if ! "$MM" $cmd --home "$T/home" >/dev/null 2>"$T/reader.err"; then
        failed=$((failed + 1))
        cat "$T/reader.err" >>"$T/reader.failures"
      fi
      echo "$calls $failed" >"$T/reader.count"
    done
  done
) &
reader=$!

t0=$(date +%s.%N)
"$MMD" --config "$T/config.json" 2>>"$T/daemon.log" &
pid=$!
peak=0
while [ "$(left)" -gt 0 ]; do
  kill -0 "$pid" 2>/dev/null || { echo "meshmarkd exited:"; cat "$T/daemon.log"; exit 1; }
  hwm=$(awk '/VmHWM/ { print $2 }' "/proc/$pid/status")
  [ "$hwm" -gt "$peak" ] && peak=$hwm
  sleep 0.05
done
t1=$(date +%s.%N)
hwm=$(awk '/VmHWM/ { print $2 }' "/proc/$pid/status")
[ "$hwm" -gt "$peak" ] && peak=$hwm
kill "$reader" 2>/dev/null; wait "$reader" 2>/dev/null || true
reader=""
kill -TERM "$pid"
wait "$pid" 2>/dev/null || true
pid=""

read -r calls failed <"$T/reader.count"
secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')
rate=$(awk -v n="$N" -v s="$secs" 'BEGIN { printf "%.0f", n / s }')
states=$(sqlite3 -cmd ".timeout 10000" "$T/home/meshmark.db" "SELECT group_concat(state || ' ' || c, ', ') FROM (SELECT state, COUNT(*) c FROM jobs GROUP BY state)")
integrity=$(sqlite3 -cmd ".timeout 10000" "$T/home/meshmark.db" "PRAGMA integrity_check")
locked=$(cat "$T/daemon.log" "$T/reader.failures" 2>/dev/null | grep -ci "locked\|busy" || true)
echo "queue load: $N no-op jobs, $W workers: ${secs} s, $rate jobs/s; peak RSS $((peak / 1024)) MB; reader: $calls calls, $failed failed; lock messages: $locked; jobs: $states; integrity_check $integrity"
mkdir -p docs/results
cat >docs/results/queue-load.md <<EOF
# Queue under load

Written by \`scripts/bench-queue-load.sh\` (JOBS_N=$N WORKERS=$W) at $(git rev-parse --short HEAD), $(nproc) cores.
$N no-op jobs inserted by another program (the queue contract's INSERT), drained by meshmarkd
while a reader runs \`meshmark jobs list\` and \`meshmark copies\` in a loop.

| measure | value |
|---|---|
| jobs | $N ($states) |
| workers | $W |
| time to drain | $secs s |
| throughput | $rate jobs/s |
| meshmarkd peak RSS | $((peak / 1024)) MB |
| reader CLI calls (failed) | $calls ($failed) |
| "locked" or "busy" messages in the daemon's log and the reader's errors | $locked |
| integrity_check | $integrity |
EOF
[ "$failed" -eq 0 ] && [ "$locked" -eq 0 ] && [ "$integrity" = ok ]
