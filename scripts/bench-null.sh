#!/usr/bin/env bash
# False-attribution calibration: how often detection names a copy that is not in the suspect.
# The shared CAD parts are protected for twelve customers by `meshmark run`; the suspects are the
# unmarked originals and one customer's decoded copy, each attacked six ways; every detection
# scores every copy of its part, and every (suspect, copy) pair whose copy is not in the suspect
# is an innocent trial. Prints, per statistic, how many innocent trials fall below each p (an
# exact test falls below alpha at most alpha of the time), and the false attributions (corrected
# p below the threshold) with a 95 % upper confidence bound on their rate. Rewrites
# docs/results/null.md.
#
# Usage: scripts/bench-null.sh WORK_DIR   (MESHMARK, MESHES, LIST as scripts/bench-detect.sh)
set -euo pipefail
BENCH_ENV="MESHMARK MESHES LIST"
. "$(dirname "$0")/bench-results.sh"
bench_results null "False attributions: innocent trials against the p-values' promise" "$@"
. "$(dirname "$0")/bench-homes.sh"
here="$(cd "$(dirname "$0")/.." && pwd)"
MM=$(realpath "${MESHMARK:-$here/build/daemon/meshmark}")
MESHES=$(realpath "${MESHES:-$here/../shared/data/meshes}")
W=${1:?usage: bench-null.sh WORK_DIR}
LIST=${LIST:-"fandisk.off bracket-3.stl blade.stl rocker.stl abc5.stl abc6.stl abc7.stl abc8.stl abc9.stl"}
customers=(c01 c02 c03 c04 c05 c06 c07 c08 c09 c10 c11 c12)
mkdir -p "$W"
W=$(realpath "$W")

config() {
  cat >"$1/meshmarkd.json" <<EOF
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": 2, "log_level": "warn", "output_format": "off"}
EOF
}

# six attacks (numbered 0-5 in the suspects' names)
attacks=("noise -A 0.002 --seed 9" "smooth -n 5" "remesh --edge 0.01" "simplify --keep 0.3" "quantize --bits 9"
         "subdivide --linear -L 1")
if [ ! -f "$W/setup/ready" ]; then
  S="$W/setup"
  bench_protect "$S" "$MESHES" "$LIST" "${customers[@]}"
  for p in $LIST; do
    stem=${p%.*}
    copy=$(ls "$S/out/c01/$stem"-*.off)
    for k in "${!attacks[@]}"; do
      read -r -a args <<<"${attacks[$k]}"
      "$MM" attack "${args[0]}" "${args[@]:1}" "$MESHES/$p" "$S/suspects/$stem--original-$k--nobody.off" >/dev/null
      "$MM" attack "${args[0]}" "${args[@]:1}" "$copy" "$S/suspects/$stem--copy-$k--c01.off" >/dev/null
    done
  done
  touch "$S/ready"
fi

bench_new_run "$W"
(cd "$R" && "$MM" run --until-empty --no-drops --config meshmarkd.json >"$R/run.txt" 2>"$R/run.log") || true
"$MM" detections --home "$R/home" --json --limit 100000 >"$R/detections.json"
"$MM" copies --home "$R/home" --json --limit 100000 >"$R/copies.json"
echo "run $R: $(cat "$R/run.txt")"
python3 "$here/scripts/null-summary.py" "$R" "$W/setup/home" "$MM" "$here/docs/results/null.json"
