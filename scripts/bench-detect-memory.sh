#!/usr/bin/env bash
# Peak memory of a detection batch: five shared CAD parts protected for two customers, then 35
# suspects (decoded copies, streams, noisy copies, order-lost STL copies, streams and decoded
# copies refined once more, noisy unmarked originals) detected by `meshmark run --until-empty` with 2 workers. Prints the
# batch's peak RSS (/usr/bin/time %M) and one line per verdict, so two builds can be compared on
# the same home (same keys, same copies): the verdict lines must be identical, and so must
# WORK_DIR/run-<n>/detections.json (every p-value of every copy tried, without row ids and times).
#
# Usage: scripts/bench-detect-memory.sh WORK_DIR [context_cache_mb]
#   MESHMARK=path/to/meshmark (default: build/daemon/meshmark); LOG_LEVEL=debug shows each
#   resynchronisation with its context size and the cache after each job (run-<n>/run.log).
# WORK_DIR/setup (home with the protected copies, suspects) is made on the first run and reused,
# so later runs, with another build or budget, detect the same suspects against the same keys.
# Each run detects in a fresh copy of that home: WORK_DIR/run-<n>.
set -euo pipefail
BENCH_ENV="MESHMARK LOG_LEVEL"
. "$(dirname "$0")/bench-results.sh"
bench_results detect-memory "Detection batch: peak memory and verdicts of 35 suspects" "$@"
. "$(dirname "$0")/bench-homes.sh"
here="$(cd "$(dirname "$0")/.." && pwd)"
MM=$(realpath "${MESHMARK:-$here/build/daemon/meshmark}")
W=${1:?usage: bench-detect-memory.sh WORK_DIR [context_cache_mb]}
budget=${2:-}
meshes="$here/../shared/data/meshes"
parts=(fandisk_quads.off fandisk.off bracket-3.stl rocker.stl blade.stl)
mkdir -p "$W"
W=$(realpath "$W")

config() {  # config DIR: a configuration for the home in DIR (with the budget, if given)
  local detect='"p_threshold": 1e-6, "max_candidates": 3'
  [ -n "$budget" ] && detect="$detect, \"context_cache_mb\": $budget"
  cat >"$1/meshmarkd.json" <<EOF
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": 2, "log_level": "${LOG_LEVEL:-warn}",
 "detect": {$detect}}
EOF
}

if [ ! -f "$W/setup/ready" ]; then
  S="$W/setup"
  budget="" bench_protect "$S" "$meshes" "${parts[*]}" alice bob
  for p in "${parts[@]}"; do
    stem=${p%.*} ext=${p##*.}
    a_dec=$(ls "$S/out/alice/$stem"-*."$ext") b_dec=$(ls "$S/out/bob/$stem"-*."$ext")
    b_mmc=$(ls "$S/out/bob/$stem"-*.mmc)
    s="$S/suspects/$stem"
    cp "$a_dec" "$s-alice-decoded.$ext"                                    # exact hash
    cp "$b_mmc" "$s-bob-stream.mmc"                                         # exact hash
    "$MM" attack noise -A 0.0005 --seed 3 "$a_dec" "$s-alice-noisy.$ext" >/dev/null  # by signature
    "$MM" attack noise -A 0.0005 --seed 4 "$b_dec" "$s-bob-noisy.stl" >/dev/null     # order lost
    "$MM" attack subdivide -L 1 "$b_mmc" "$s-bob-l1.off" >/dev/null        # a polyhedron refined once
    "$MM" attack subdivide -L 1 "$a_dec" "$s-alice-l4.$ext" >/dev/null     # a decoded copy refined once
    "$MM" attack noise -A 0.0005 --seed 5 "$meshes/$p" "$s-unmarked-noisy.$ext" >/dev/null
  done
  touch "$S/ready"
fi

bench_new_run "$W"
/usr/bin/time -f "%M %U %S" -o "$R/time" "$MM" run --until-empty --no-drops --workers 2 \
  --config "$R/meshmarkd.json" >"$R/run.txt" 2>"$R/run.log" || true
read -r rss user sys <"$R/time"
echo "run $R: $(cat "$R/run.txt")"
echo "peak RSS $((rss / 1024)) MB ($rss kB), CPU user ${user} s sys ${sys} s, budget ${budget:-default}"
"$MM" detections --home "$R/home" --json --limit 1000 | python3 -c '
import json, sys
rows = sorted(json.load(sys.stdin), key=lambda r: r["suspect_name"])
for r in rows:
    for k in ("id", "created_at", "job_id", "detected_at"):
        r.pop(k, None)
json.dump(rows, open(sys.argv[1], "w"), indent=1, sort_keys=True)
for r in rows:
    d = r["details"]
    print("%-34s %-18s copy %-4s %-12s -log10 p %.6f candidates %d" % (
        r["suspect_name"], r["verdict"], r["copy_id"], r["resync_method"],
        d.get("best_neg_log10_corrected_p", 0), len(d.get("candidates", []))))
' "$R/detections.json"
