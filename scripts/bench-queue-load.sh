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
cat >"$T/config.json" <<EOF
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": $W, "poll_interval_ms": 100,
 "evidence": {"auto": false}, "log_level": "warn"}
EOF
left() { sqlite3 -cmd ".timeout 10000" "$T/home/meshmark.db" "SELECT COUNT(*) FROM jobs WHERE state <> 'completed'"; }

# drain READER: a fresh home with N queued jobs, drained by meshmarkd, with (1) or without (0)
# the reader; sets secs, rate, peak, calls, failed, states, integrity, locked.
drain() {
  rm -rf "$T/home" "$T/reader.count" "$T/reader.failures" "$T/daemon.log"
  echo "0 0" >"$T/reader.count"
  "$MM" init --home "$T/home" >/dev/null
  sqlite3 "$T/home/meshmark.db" "PRAGMA busy_timeout = 10000; PRAGMA wal_autocheckpoint = 0;
    WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < $N)
    INSERT INTO jobs (kind, payload_json, idempotency_key) SELECT 'noop', '{}', 'load:' || i FROM n;" >/dev/null
  if [ "$1" = 1 ]; then
    (  # the reader: what an operator's status checks do meanwhile
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
  fi
  t0=$(date +%s.%N)
  "$MMD" --config "$T/config.json" 2>>"$T/daemon.log" &
  pid=$!
  peak=0
  while [ "$(left)" -gt 0 ]; do
    kill -0 "$pid" 2>/dev/null || { echo "meshmarkd exited:"; cat "$T/daemon.log"; exit 1; }
    hwm=$(awk '/VmHWM/ { print $2 }' "/proc/$pid/status")
    [ "$hwm" -gt "$peak" ] && peak=$hwm
    sleep 0.2
  done
  t1=$(date +%s.%N)
  hwm=$(awk '/VmHWM/ { print $2 }' "/proc/$pid/status")
  [ "$hwm" -gt "$peak" ] && peak=$hwm
  if [ -n "$reader" ]; then kill "$reader" 2>/dev/null; wait "$reader" 2>/dev/null || true; fi
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
}

drain 0
alone_secs=$secs alone_rate=$rate alone_peak=$peak alone_states=$states alone_integrity=$integrity alone_locked=$locked
echo "queue alone: $N no-op jobs, $W workers: ${secs} s, $rate jobs/s; peak RSS $((peak / 1024)) MB; lock messages: $locked; jobs: $states; integrity_check $integrity"
drain 1
echo "queue load: $N no-op jobs, $W workers: ${secs} s, $rate jobs/s; peak RSS $((peak / 1024)) MB; reader: $calls calls, $failed failed; lock messages: $locked; jobs: $states; integrity_check $integrity"
mkdir -p docs/results
cat >docs/results/queue-load.md <<EOF
# Queue under load

Written by \`scripts/bench-queue-load.sh\` (JOBS_N=$N WORKERS=$W) at $(git rev-parse --short HEAD), $(nproc) cores.
$N no-op jobs inserted by another program (the queue contract's INSERT), drained by meshmarkd
alone, then again while a reader runs \`meshmark jobs list\` and \`meshmark copies\` in a loop
(each call a new process: on 2 cores the reader's processes take about half the CPU).

| measure | alone | with the reader |
|---|---|---|
| jobs | $N ($alone_states) | $N ($states) |
| workers | $W | $W |
| time to drain | $alone_secs s | $secs s |
| throughput | $alone_rate jobs/s | $rate jobs/s |
| meshmarkd peak RSS | $((alone_peak / 1024)) MB | $((peak / 1024)) MB |
| reader CLI calls (failed) | - | $calls ($failed) |
| "locked" or "busy" messages in the daemon's log and the reader's errors | $alone_locked | $locked |
| integrity_check | $alone_integrity | $integrity |
EOF
[ "$alone_locked" -eq 0 ] && [ "$alone_integrity" = ok ] && [ "$failed" -eq 0 ] && [ "$locked" -eq 0 ] && [ "$integrity" = ok ]
