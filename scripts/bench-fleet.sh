#!/usr/bin/env bash
# A fleet of meshmarkd nodes on one PostgreSQL (a throwaway server of Debian's postgresql-15 on a
# Unix socket in a temp folder, fsync on). Rewrites docs/results/fleet.md.
#  1. Scaling: 1, 2 and 4 nodes (one worker each) over the same N protect jobs (N sample parts,
#     one customer): jobs/s and the ratio to one node, then the checks below and the job table's
#     dead tuples.
#  2. Faults, each ROUNDS times, on a fresh database of FAULT_JOBS jobs with two nodes:
#     - node:    kill -9 of a node while it runs a job; a replacement node starts;
#     - leader:  kill -9 of the leader; the seconds until another node holds the lease;
#     - stale:   a node stopped (SIGSTOP) mid-job past its lease, resumed once another node has
#                completed that job: its late completion must be refused;
#     - restart: PostgreSQL restarted (fast shutdown) in the middle of the run.
#     Checks after every run: every job completed, one copy per job (none twice),
#     every asset's and polyhedron's blob present and hashing to its name.
#  3. The queue alone: no-op jobs/s on SQLite and on PostgreSQL (bench_queue).
# Usage: scripts/bench-fleet.sh [build-dir]; N=1000, ROUNDS=20, FAULT_JOBS=12.
set -euo pipefail
BENCH_ENV="N ROUNDS FAULT_JOBS"
. "$(dirname "$0")/bench-results.sh"
bench_results fleet "A fleet of meshmarkd nodes on one PostgreSQL: scaling, faults, queue" "$@"
here="$(cd "$(dirname "$0")/.." && pwd)"
build=$(realpath "${1:-$here/build}")
N=${N:-1000}
ROUNDS=${ROUNDS:-20}
FAULT_JOBS=${FAULT_JOBS:-12}
PGBIN=/usr/lib/postgresql/15/bin
[ -x "$PGBIN/initdb" ] || { echo "bench-fleet: PostgreSQL 15 is not installed ($PGBIN/initdb)" >&2; exit 1; }
cmake --build "$build" --target meshmark meshmarkd bench_queue -j2 >&2
MM=$build/daemon/meshmark
MMD=$build/daemon/service/meshmarkd

T=$(mktemp -d /tmp/mm-bench-fleet-XXXXXX)
PIDS=()
cleanup() {
  for p in "${PIDS[@]:-}"; do [ -n "$p" ] && kill -9 "$p" 2>/dev/null || true; done
  pg stop -m immediate >/dev/null 2>&1 || true
  rm -rf "$T"
}
trap cleanup EXIT
mkdir -p "$T/pg"
as=()
if [ "$(id -u)" = 0 ]; then chmod 711 "$T"; chown postgres "$T/pg"; as=(runuser -u postgres --); fi
pg() { "${as[@]}" "$PGBIN/pg_ctl" -D "$T/pg/data" -l "$T/pg/server.log" "$@"; }
"${as[@]}" "$PGBIN/initdb" -D "$T/pg/data" -U postgres --auth=trust -E UTF8 --locale=C >/dev/null
pg_start() { pg -w -o "-k $T/pg -c listen_addresses='' -p 5432 -c max_connections=200" start >/dev/null; }
pg_start
conn() { echo "host=$T/pg port=5432 user=postgres dbname=$1"; }
sql() { psql "$(conn "$1")" -XAtqc "$2"; }

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

echo "== sample parts"
mkdir -p "$T/parts"
families=(chamfered_block plate_with_holes flanged_cylinder)
for i in $(seq 1 "$N"); do
  "$MM" sample "${families[$((i % 3))]}" --variant "$((i / 3 + 1))" "$T/parts/s.off" >/dev/null
  # A comment line makes each file a part of its own (as revisions of one shape are in a vault).
  { head -1 "$T/parts/s.off"; echo "# bench part $i"; tail -n +2 "$T/parts/s.off"; } >"$T/parts/p$i.off"
done
rm "$T/parts/s.off"
shapes=$(for f in "$T"/parts/*.off; do grep -v '^#' "$f" | md5sum; done | sort -u | wc -l)
echo "$N parts of the three sample families (seeded dimensions), $shapes distinct shapes"

# A fresh database with a home (master key, customer alpha) and `jobs` protect jobs submitted.
setup() {  # setup DB JOBS
  local db=$1 jobs=$2
  psql "$(conn postgres)" -XAtqc "CREATE DATABASE $db"
  rm -rf "$T/$db" && mkdir -p "$T/$db"
  MESHMARK_STORE="$(conn "$db")" "$MM" init --home "$T/$db/home" >/dev/null
  MESHMARK_STORE="$(conn "$db")" "$MM" customer add alpha --home "$T/$db/home" >/dev/null
  config "$db" 0 >/dev/null
  local files=()
  for i in $(seq 1 "$jobs"); do files+=("$T/parts/p$i.off"); done
  "$MM" submit protect --config "$T/$db/node0.json" --customer alpha "${files[@]}" >/dev/null
}
config() {  # config DB I: the config file of node I, printed
  local db=$1 i=$2
  mkdir -p "$T/$db/drop$i" "$T/$db/out$i"
  cat >"$T/$db/node$i.json" <<EOF
{"home": "$T/$db/home", "drop_dir": "$T/$db/drop$i", "output_dir": "$T/$db/out$i", "workers": 1,
 "lease_seconds": 5, "heartbeat_seconds": 1, "poll_interval_ms": 200, "output_format": "off",
 "log_level": "info", "store": {"postgres": "$(conn "$db")"}}
EOF
  echo "$T/$db/node$i.json"
}
start_node() {  # start_node DB I: runs node I, its pid in $started
  local cfg
  cfg=$(config "$1" "$2")
  "$MMD" --config "$cfg" 2>>"$T/$1/node$2.log" &
  started=$!
  PIDS+=("$started")
}
stop_nodes() { for p in "$@"; do kill -TERM "$p" 2>/dev/null || true; done; for p in "$@"; do wait "$p" 2>/dev/null || true; done; }
wait_done() {  # wait_done DB JOBS SECONDS: until every job completed; 1 if not in time
  local end=$(($(date +%s) + $3))
  while [ "$(sql "$1" "SELECT COUNT(*) FROM jobs WHERE kind = 'protect' AND state = 'completed'")" -lt "$2" ]; do
    [ "$(date +%s)" -lt "$end" ] || return 1
    sleep 0.1
  done
}
# Every job completed, one copy per job, every blob whole: "ok", or what is wrong.
check() {  # check DB JOBS
  local db=$1 jobs=$2 bad=()
  local done copies distinct missing corrupt
  done=$(sql "$db" "SELECT COUNT(*) FROM jobs WHERE kind = 'protect' AND state = 'completed'")
  copies=$(sql "$db" "SELECT COUNT(*) FROM issued_copies")
  distinct=$(sql "$db" "SELECT COUNT(DISTINCT job_id) FROM issued_copies")
  missing=$(sql "$db" "SELECT COUNT(*) FROM (SELECT sha256 FROM assets UNION SELECT polyhedron_blob FROM polyhedra
                        UNION SELECT basis_blob FROM polyhedra WHERE basis_blob <> '') r
                        WHERE NOT EXISTS (SELECT 1 FROM blobs b WHERE b.sha256 = r.sha256)")
  corrupt=$(sql "$db" "SELECT COUNT(*) FROM (SELECT b.sha256, b.size,
                        encode(sha256(COALESCE(string_agg(c.data, ''::bytea ORDER BY c.seq), ''::bytea)), 'hex') AS h,
                        COALESCE(SUM(length(c.data)), 0) AS n
                        FROM blobs b LEFT JOIN blob_chunks c USING (sha256) GROUP BY b.sha256, b.size) x
                        WHERE h <> sha256 OR n <> size")
  [ "$done" = "$jobs" ] || bad+=("$done of $jobs jobs completed")
  [ "$copies" = "$jobs" ] && [ "$distinct" = "$jobs" ] || bad+=("$copies copies from $distinct jobs, for $jobs jobs")
  [ "$missing" = 0 ] || bad+=("$missing blobs missing")
  [ "$corrupt" = 0 ] || bad+=("$corrupt blobs not hashing to their name")
  if [ ${#bad[@]} -eq 0 ]; then echo ok; else (IFS=';'; echo "${bad[*]}"); fi
}

echo
echo "== scaling: $N protect jobs, nodes of one worker each, $(nproc) cores"
printf '%-6s %9s %8s %9s %7s %s\n' nodes seconds jobs/s vs_1_node claims dead_tuples/live
base=""
for n in 1 2 4; do
  db=scale$n
  setup "$db" "$N"
  t0=$(now)
  nodes=()
  for i in $(seq 1 "$n"); do start_node "$db" "$i"; nodes+=("$started"); done
  wait_done "$db" "$N" 3600 || { echo "scaling $n: not done in an hour" >&2; exit 1; }
  t1=$(now)
  stop_nodes "${nodes[@]}"
  secs=$(elapsed "$t0" "$t1")
  rate=$(awk -v n="$N" -v s="$secs" 'BEGIN { printf "%.2f", n / s }')
  [ -n "$base" ] || base=$rate
  extra=$(sql "$db" "SELECT COUNT(*) FROM jobs WHERE attempt <> 1")
  sleep 1  # statistics reach pg_stat_user_tables within a second
  dead=$(sql "$db" "SELECT n_dead_tup || '/' || n_live_tup FROM pg_stat_user_tables WHERE relname = 'jobs'")
  printf '%-6s %9s %8s %9s %7s %s\n' "$n" "$secs" "$rate" "$(awk -v r="$rate" -v b="$base" 'BEGIN { printf "%.2fx", r / b }')" \
    "$((N + extra))" "$dead"
  c=$(check "$db" "$N")
  [ "$c" = ok ] || { echo "scaling $n nodes: $c" >&2; exit 1; }
done
echo "checks: every job completed once (claims = jobs), one copy per job, every blob present and whole"

echo
echo "== faults: $ROUNDS rounds each, $FAULT_JOBS protect jobs and two nodes per round (lease 5 s, a beat a second)"
# The pid of the node running a job now ("" if none): worker ids are host:pid:wN.
running_pid() { sql "$1" "SELECT split_part(worker_id, ':', 2) FROM jobs WHERE state = 'running' LIMIT 1"; }
declare -A passed detail
for kind in node leader stale restart; do passed[$kind]=0; detail[$kind]=""; done
round=0
for r in $(seq 1 "$ROUNDS"); do
  for kind in node leader stale restart; do
    round=$((round + 1))
    db=f$round
    setup "$db" "$FAULT_JOBS"
    start_node "$db" 1; a=$started
    start_node "$db" 2; b=$started
    nodes=("$a" "$b")
    note=""
    case $kind in
      node)
        victim=""
        until [ -n "$victim" ]; do victim=$(running_pid "$db"); done
        kill -9 "$victim"
        start_node "$db" 3; nodes+=("$started")
        ;;
      leader)
        leader=""
        until [ -n "$leader" ]; do leader=$(sql "$db" "SELECT split_part(node, ':', 2) FROM leader WHERE until > mm_now_ms()"); done
        kill -9 "$leader"
        t0=$(now)
        until [ -n "$(sql "$db" "SELECT node FROM leader WHERE until > mm_now_ms() AND split_part(node, ':', 2) <> '$leader'")" ]; do
          sleep 0.05
        done
        note=$(elapsed "$t0" "$(now)")
        start_node "$db" 3; nodes+=("$started")
        ;;
      stale)
        # Stop a node inside a job; if the job ended before the stop landed, let it go and try again.
        while :; do
          victim=$(running_pid "$db")
          [ -n "$victim" ] || continue
          kill -STOP "$victim"
          job=$(sql "$db" "SELECT id FROM jobs WHERE state = 'running' AND split_part(worker_id, ':', 2) = '$victim'")
          [ -n "$job" ] && break
          kill -CONT "$victim"
        done
        until [ "$(sql "$db" "SELECT state FROM jobs WHERE id = $job")" = completed ]; do sleep 0.1; done
        kill -CONT "$victim"
        ;;
      restart)
        until [ "$(sql "$db" "SELECT COUNT(*) FROM jobs WHERE state = 'completed'")" -ge 2 ]; do sleep 0.02; done
        pg restart -m fast -w -o "-k $T/pg -c listen_addresses='' -p 5432 -c max_connections=200" >/dev/null
        ;;
    esac
    ok=1
    wait_done "$db" "$FAULT_JOBS" 120 || ok=0
    if [ "$kind" = stale ]; then
      # The resumed node's result for the re-claimed job is refused (its copy was never issued).
      sleep 2
      grep -q "job $job: result dropped, lease lost" "$T/$db/node"*.log || { ok=0; echo "round $round ($kind): no refused completion for job $job" >&2; }
    fi
    stop_nodes "${nodes[@]}"
    c=$(check "$db" "$FAULT_JOBS")
    if [ "$c" != ok ] || [ $ok = 0 ]; then
      echo "round $round ($kind): $c" >&2
      sed -n '1,200p' "$T/$db"/node*.log | grep -E "warn|error" | head -20 >&2 || true
    else
      passed[$kind]=$((${passed[$kind]} + 1))
    fi
    [ -z "$note" ] || detail[$kind]="${detail[$kind]} $note"
    psql "$(conn postgres)" -XAtqc "DROP DATABASE $db" >/dev/null
  done
done
printf '%-8s %s\n' fault "rounds passed (every job once, one copy each, blobs whole)"
for kind in node leader stale restart; do
  line="${passed[$kind]} of $ROUNDS"
  if [ "$kind" = leader ]; then
    line="$line; leader replaced after (s): $(echo "${detail[$kind]}" | tr ' ' '\n' | grep . | sort -n |
      awk '{ v[NR] = $1 } END { printf "min %.2f, median %.2f, max %.2f", v[1], v[int((NR + 1) / 2)], v[NR] }') (lease 3 s)"
  fi
  [ "$kind" = stale ] && line="$line; the stopped node's late completion refused each time"
  printf '%-8s %s\n' "$kind" "$line"
done
failed=0
for kind in node leader stale restart; do [ "${passed[$kind]}" = "$ROUNDS" ] || failed=1; done

echo
echo "== the queue alone: no-op jobs (enqueue, claim, complete), SQLite and PostgreSQL"
"$build/tests/store/bench_queue" --benchmark_min_time=2 --benchmark_counters_tabular=true
exit $failed
