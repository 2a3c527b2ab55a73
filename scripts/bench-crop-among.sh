#!/usr/bin/env bash
# A cropped leak found among many stored assets: N distinct sample parts from the generated part families
# (plates with holes, chamfered blocks, flanged cylinders with seeded dimensions, all in one
# frame, so that many share whole regions) are protected for alice by `meshmark run`; for every
# TARGETS-th part, alice's decoded copy cropped to half of its longest side (low and high end) is
# a leak, and the unmarked original cropped the same way an innocent suspect. Every suspect is
# detected by `meshmark run`: whether the leak's asset was found and alice named, the candidates
# tried, -log10 p, the seconds. Rewrites docs/results/crop-among.md.
#
# Usage: scripts/bench-crop-among.sh WORK_DIR
#   MESHMARK=path/to/meshmark (default build/daemon/meshmark), N=1000 parts, EVERY=50 (every
#   EVERY-th part is a target), WORKERS=2.
# WORK_DIR/setup (home, copies, suspects) is made once and reused; each run detects in a fresh
# copy of the home (WORK_DIR/run-<n>).
set -euo pipefail
BENCH_ENV="MESHMARK N EVERY WORKERS"
. "$(dirname "$0")/bench-results.sh"
bench_results crop-among "A cropped leak found among many stored assets" "$@"
. "$(dirname "$0")/bench-homes.sh"
here="$(cd "$(dirname "$0")/.." && pwd)"
MM=$(realpath "${MESHMARK:-$here/build/daemon/meshmark}")
W=${1:?usage: bench-crop-among.sh WORK_DIR}
N=${N:-1000}
EVERY=${EVERY:-50}
WORKERS=${WORKERS:-2}
families=(plate_with_holes chamfered_block flanged_cylinder)
mkdir -p "$W"
W=$(realpath "$W")

config() {  # config DIR
  cat >"$1/meshmarkd.json" <<JSON
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": $WORKERS, "log_level": "warn",
 "output_format": "off"}
JSON
}

S="$W/setup"
if [ ! -f "$S/protected" ]; then
  mkdir -p "$W/parts"
  # N distinct parts, part i of family i mod 3: a member that repeats an earlier one (the same
  # bytes) is skipped.
  parts="" i=0
  declare -A seen=() next=()
  while [ "$i" -lt "$N" ]; do
    f=${families[$((i % 3))]}
    v=$((${next[$f]:-0} + 1))
    next[$f]=$v
    "$MM" sample "$f" "$W/parts/candidate.off" --variant "$v" >/dev/null
    sum=$(sha256sum "$W/parts/candidate.off" | cut -c1-64)
    [ -z "${seen[$sum]:-}" ] || continue
    seen[$sum]=1
    i=$((i + 1))
    name=$(printf "part%04d-%s" "$i" "$f")
    mv "$W/parts/candidate.off" "$W/parts/$name.off"
    parts="$parts $name.off"
  done
  start=$(date +%s)
  bench_protect "$S" "$W/parts" "$parts" alice
  echo "protected $N parts for alice in $(($(date +%s) - start)) s ($WORKERS workers)" >"$S/protected"
fi
cat "$S/protected"
if [ ! -f "$S/ready" ]; then
  rm -rf "$S/suspects" && mkdir -p "$S/suspects"
  for i in $(seq "$EVERY" "$EVERY" "$N"); do
    stem=$(basename "$(ls "$W/parts/$(printf "part%04d" "$i")"-*.off)" .off)
    decoded=$(ls "$S/out/alice/$stem"-*.off 2>/dev/null || true)
    [ -n "$decoded" ] || { echo "$stem: not protected"; continue; }
    "$MM" attack crop --keep 0.5 "$decoded" "$S/suspects/$stem--low--alice.off" >/dev/null
    "$MM" attack crop --keep 0.5 --from-high "$decoded" "$S/suspects/$stem--high--alice.off" >/dev/null
    "$MM" attack crop --keep 0.5 "$W/parts/$stem.off" "$S/suspects/$stem--low--nobody.off" >/dev/null
  done
  touch "$S/ready"
fi

bench_detect_run "$W"
"$MM" assets --home "$R/home" --json --limit 100000 >"$R/assets.json"
echo "stored assets: $(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))))" "$R/assets.json")"
echo "detect jobs: wall ${wall} s, CPU user ${user} s, peak RSS $((rss / 1024)) MB, $WORKERS workers"
python3 - "$R" "$W/parts" <<'PY'
import hashlib, json, sys
run, parts = sys.argv[1:3]
dets = json.load(open(run + "/detections.json"))
shas = {a["id"]: a["sha256"] for a in json.load(open(run + "/assets.json"))}
rows = []
for d in dets:
    stem, end, truth = d["suspect_name"].rsplit(".", 1)[0].split("--")
    det = d["details"]
    named = [a for a in det.get("attributed", [])]
    found = shas.get(d.get("asset_id")) == hashlib.sha256(open("%s/%s.off" % (parts, stem), "rb").read()).hexdigest()
    if truth == "nobody":
        outcome = "WRONG" if named else "ok"
    elif not named:
        outcome = "missed"
    else:
        outcome = "traced" if found else "WRONG"
    rows.append((stem, end, truth, d["verdict"], len(det.get("candidates", [])), "yes" if found else "no",
                 det.get("best_neg_log10_corrected_p", 0), det.get("seconds", 0.0), outcome))
rows.sort()
print("%-28s %-5s %-7s %-20s %10s %11s %8s %7s %s" % ("part", "crop", "leaker", "verdict", "candidates", "asset found",
                                                     "-log10p", "seconds", "outcome"))
for r in rows:
    print("%-28s %-5s %-7s %-20s %10d %11s %8.1f %7.2f %s" % r)
leaks = [r for r in rows if r[2] != "nobody"]
innocents = [r for r in rows if r[2] == "nobody"]
secs = sorted(r[7] for r in rows)
print()
print("leaks traced: %d of %d; wrong customer or asset: %d; innocents attributed: %d of %d" % (
    sum(r[8] == "traced" for r in leaks), len(leaks), sum(r[8] == "WRONG" for r in leaks),
    sum(r[8] == "WRONG" for r in innocents), len(innocents)))
if secs:
    print("seconds per detection: median %.2f, max %.2f" % (secs[len(secs) // 2], secs[-1]))
PY
