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
python3 - "$R" "$W/setup/home" "$MM" <<'PY'
import json, math, subprocess, sys
run, home, mm = sys.argv[1:4]
dets = json.load(open(run + "/detections.json"))
customers = {c["id"]: c["name"] for c in json.loads(subprocess.check_output([mm, "customer", "list", "--home", home, "--json"]))}
copies = json.load(open(run + "/copies.json"))
copy_customer = {c["id"]: customers.get(c["customer_id"], c.get("customer")) for c in copies}
ln10 = math.log(10)
trials, leaks = [], []
for d in dets:
    stem, kind, truth = d["suspect_name"].rsplit(".", 1)[0].split("--")
    tried = d["details"].get("copies_tried", 0)
    for cand in d["details"].get("candidates", []):
        for s in cand["copies"]:
            who = copy_customer.get(s["copy_id"])
            row = (s["sign_neg_log10_p"], s["matched_neg_log10_p"], -math.log10(max(s["p_value"], 1e-300)), kind[-1])
            (leaks if who == truth else trials).append(row)
n = len(trials)
print("innocent trials: %d (suspect, copy) pairs over %d detections; %d leaked-copy scores besides" % (n, len(dets), len(leaks)))
print()
print("%-10s %12s %12s %12s %12s" % ("p below", "expected", "sign count", "matched", "combined"))
for alpha in (0.1, 0.01, 0.001, 1e-4, 1e-6, 1e-9):
    t = -math.log10(alpha)
    counts = [sum(r[i] > t for r in trials) for i in range(3)]
    print("%-10g %12.1f %12d %12d %12d" % (alpha, alpha * n, *counts))
# One source under its six attacks keeps much of its recovered pattern and meets the same copies'
# keys, so its trials are not independent across attacks; within one attack they are.
print()
print("per attack (independent trials within each): below 0.01 / below 0.001, sign count | matched | combined")
for k in sorted({r[3] for r in trials}):
    rs = [r for r in trials if r[3] == k]
    cells = ["%d / %d" % (sum(r[i] > 2 for r in rs), sum(r[i] > 3 for r in rs)) for i in range(3)]
    print("attack %s: %4d trials, expected %.1f / %.2f:  %s | %s | %s" % (k, len(rs), 0.01 * len(rs), 0.001 * len(rs), *cells))
false = 0
for d in dets:
    stem, kind, truth = d["suspect_name"].rsplit(".", 1)[0].split("--")
    for a in d["details"].get("attributed", []):
        if customers.get(a["customer_id"]) != truth:
            false += 1
bound = 1 - 0.05 ** (1.0 / n) if false == 0 and n else float("nan")
print()
print("false attributions (corrected p < threshold, a copy not in the suspect): %d of %d trials" % (false, n))
if false == 0:
    print("95 %% upper confidence bound on the false-attribution rate per trial: %.2g (3/n rule %.2g)" % (bound, 3.0 / n))
print("largest innocent -log10 p: sign %.2f, matched %.2f, combined %.2f" % tuple(max(r[i] for r in trials) for i in range(3)))
PY
