#!/usr/bin/env bash
# Fault injection over the whole service, as SQLite tests itself: meshmarkd is killed (SIGKILL) after
# a seeded random life of 1 to 6 s, then `meshmark run` is made to fail its Nth file write (MESHMARK_FAIL_WRITE)
# and its Nth database commit (MESHMARK_FAIL_DB_WRITE), N = 1, 2, ... Work keeps arriving (protect
# jobs for two customers and a detect job per new part). At the end a clean daemon drains the queue
# and the script checks: every job completed exactly once (one copy per protect job, one detection
# per detect job, none discarded), every file a copy names exists with its recorded SHA-256, no
# file in the output folder that no copy names, no temporary file, every blob matches its name,
# PRAGMA integrity_check and foreign_key_check clean. Exit 1 on any violation.
# Usage: scripts/torture.sh [KILLS] [FAULTS] [--results]   (default 100 20; MESHMARK, TORTURE_SEED)
#        --results writes docs/results/torture.md.
set -euo pipefail
cd "$(dirname "$0")/.."
RESULTS=0
args=()
for a in "$@"; do [ "$a" = "--results" ] && RESULTS=1 || args+=("$a"); done
KILLS=${args[0]:-100}
FAULTS=${args[1]:-20}
MM=$(realpath "${MESHMARK:-build/daemon/meshmark}")
MMD=$(realpath "${MESHMARKD:-$(dirname "$MM")/service/meshmarkd}")
RANDOM=${TORTURE_SEED:-1}
T=$(mktemp -d /tmp/meshmark-torture.XXXXXX)
pid=""
cleanup() { [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null; rm -rf "$T"; }
trap cleanup EXIT
mkdir -p "$T"/{drop,out,parts}
H="$T/home"
"$MM" init --home "$H" >/dev/null
for c in alice bob; do "$MM" customer add --home "$H" "$c" >/dev/null; done
cat >"$T/config.json" <<EOF
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": 2, "lease_seconds": 5,
 "heartbeat_seconds": 1, "poll_interval_ms": 100, "evidence": {"auto": false}, "log_level": "warn"}
EOF
q() { sqlite3 -cmd ".timeout 10000" "$H/meshmark.db" "$1"; }
pending() { q "SELECT COUNT(*) FROM jobs WHERE state IN ('available', 'retryable', 'running')"; }
for s in chamfered_block plate_with_holes flanged_cylinder; do "$MM" sample "$s" "$T/parts/$s.off" >/dev/null; done
parts=0
# One new part (a turned sample, so every part is a distinct asset): protect for alice and bob,
# detect of the part itself.
new_part() {
  local bases=(chamfered_block plate_with_holes flanged_cylinder)
  parts=$((parts + 1))
  local f="$T/parts/part$parts.off"
  "$MM" attack similarity --rotate "$parts" "$T/parts/${bases[$((parts % 3))]}.off" "$f" >/dev/null
  for c in alice bob; do "$MM" submit protect --home "$H" --customer "$c" "$f" >/dev/null; done
  "$MM" submit detect --home "$H" "$f" >/dev/null
}
start=$(date +%s)

# 1. Kill storm.
for ((i = 1; i <= KILLS; i++)); do
  while [ "$(pending)" -lt 6 ]; do new_part; done
  "$MMD" --config "$T/config.json" >>"$T/daemon.log" 2>&1 &
  pid=$!
  sleep "$(awk -v r=$RANDOM 'BEGIN { printf "%.2f", 1 + 5 * r / 32767 }')"  # a life of 1 to 6 s
  kill -9 "$pid"
  wait "$pid" 2>/dev/null || true
  pid=""
done

# 2. The Nth file write, then the Nth database commit, of a run fails.
for ((n = 1; n <= FAULTS; n++)); do
  for var in MESHMARK_FAIL_WRITE MESHMARK_FAIL_DB_WRITE; do
    [ "$(pending)" -ge 3 ] || new_part
    env "$var=$n" "$MM" run -c "$T/config.json" --until-empty --no-drops >>"$T/run.log" 2>&1 || true
  done
done

# 3. A clean daemon drains the queue (rescuing what the kills and faults left running).
"$MMD" --config "$T/config.json" >>"$T/daemon.log" 2>&1 &
pid=$!
for _ in $(seq 600); do
  [ "$(pending)" -eq 0 ] && break
  sleep 0.5
done
kill -TERM "$pid"
wait "$pid" 2>/dev/null || true
pid=""
secs=$(($(date +%s) - start))

python3 - "$H" "$T/out" "$parts" "$KILLS" "$FAULTS" "$secs" "$RESULTS" "$(git rev-parse --short HEAD)" "$(nproc)" <<'EOF'
import hashlib, json, os, sqlite3, sys
home, out, parts, kills, faults, secs, results, commit, cores = sys.argv[1:]
parts, kills, faults = int(parts), int(kills), int(faults)
db = sqlite3.connect(os.path.join(home, "meshmark.db"))
bad = []
def sha(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()
states = dict(db.execute("SELECT state, COUNT(*) FROM jobs GROUP BY state"))
jobs = sum(states.values())
if states.get("completed", 0) != jobs:
    bad.append(f"jobs not all completed: {states}")
protect = db.execute("SELECT COUNT(*) FROM jobs WHERE kind = 'protect'").fetchone()[0]
detect = db.execute("SELECT COUNT(*) FROM jobs WHERE kind = 'detect'").fetchone()[0]
if protect != 2 * parts or detect != parts:
    bad.append(f"{protect} protect and {detect} detect jobs for {parts} parts")
copies = db.execute("SELECT COUNT(*), COUNT(DISTINCT asset_id || ':' || customer_id), "
                    "COUNT(DISTINCT job_id) FROM issued_copies").fetchone()
if copies != (protect, protect, protect):
    bad.append(f"copies (rows, distinct asset:customer, distinct jobs) {copies}, expected {protect} each")
dets = db.execute("SELECT COUNT(*), COUNT(DISTINCT job_id) FROM detections").fetchone()
if dets != (detect, detect):
    bad.append(f"detections (rows, distinct jobs) {dets}, expected {detect} each")
named = set()
for (outputs,) in db.execute("SELECT outputs_json FROM issued_copies"):
    for f in json.loads(outputs)["files"]:
        named.add(os.path.realpath(f["path"]))
        if not os.path.exists(f["path"]):
            bad.append(f"missing copy file {f['path']}")
        elif sha(f["path"]) != f["sha256"]:
            bad.append(f"hash mismatch {f['path']}")
on_disk = {os.path.realpath(os.path.join(d, n)) for d, _, ns in os.walk(out) for n in ns}
for p in sorted(on_disk - named):
    bad.append(f"orphan or temporary file {p}")
blobs = 0
for d, _, ns in os.walk(os.path.join(home, "blobs")):
    for n in ns:
        blobs += 1
        if sha(os.path.join(d, n)) != n:
            bad.append(f"blob {n} does not match its content")
integrity = db.execute("PRAGMA integrity_check").fetchone()[0]
fk = db.execute("PRAGMA foreign_key_check").fetchall()
if integrity != "ok" or fk:
    bad.append(f"integrity_check {integrity}, foreign_key_check {fk}")
rescues, max_attempt = db.execute("SELECT SUM(rescues), MAX(attempt) FROM jobs").fetchone()
failures = db.execute("SELECT COUNT(*) FROM jobs, json_each(jobs.errors_json)").fetchone()[0]
lost = jobs - states.get("completed", 0)
dup = (copies[0] - copies[2]) + (dets[0] - dets[1])
summary = (f"{kills} kills, {faults} file-write and {faults} commit faults; {jobs} jobs ({protect} protect, "
           f"{detect} detect) over {parts} parts; {lost} lost, {dup} duplicated; {copies[0]} copies with "
           f"{len(named)} files, {blobs} blobs, all hashes match; {rescues} rescues from killed workers, "
           f"{failures} recorded errors, at most {max_attempt} claims of one job; integrity_check {integrity}; "
           f"{secs} s")
print("torture: " + summary)
for b in bad[:40]:
    print("torture: FAILED: " + b, file=sys.stderr)
if results == "1" and not bad:
    with open("docs/results/torture.md", "w") as f:
        f.write("# Kill and fault torture\n\n"
                f"`scripts/torture.sh {kills} {faults} --results` at {commit}, {cores} cores.\n\n"
                "| measure | value |\n|---|---|\n"
                f"| daemon kills (SIGKILL at seeded random moments) | {kills} |\n"
                f"| runs with the Nth file write failing (N = 1..{faults}) | {faults} |\n"
                f"| runs with the Nth database commit failing (N = 1..{faults}) | {faults} |\n"
                f"| jobs (protect / detect) | {jobs} ({protect} / {detect}) |\n"
                f"| jobs lost | {lost} |\n| jobs duplicated | {dup} |\n"
                f"| issued copies, their files, blobs | {copies[0]}, {len(named)}, {blobs} (every hash matches) |\n"
                f"| orphan or temporary files | 0 |\n"
                f"| rescues from killed workers | {rescues} |\n"
                f"| errors recorded on jobs | {failures} |\n"
                f"| most claims of one job | {max_attempt} |\n"
                f"| integrity_check | {integrity} |\n| wall time | {secs} s |\n")
sys.exit(1 if bad else 0)
EOF
