#!/usr/bin/env bash
# Robustness benchmark of detection, through the product as a user runs it: the shared CAD parts
# are protected for three customers by `meshmark run`; one customer's decoded copy of each part
# (the leaker goes round the three) is attacked with `meshmark attack` at several strengths, and
# innocent suspects are made from the unmarked originals; every suspect is detected by
# `meshmark run` and the verdicts are tabled: expected and named customer, -log10 of the corrected
# p-value, the resynchronisation path, the seconds. Rewrites docs/results/detect.md and plots
# -log10 p against strength per attack (docs/results/detect-<attack>.png); with TOLERANCE set,
# docs/results/detect-tolerance-<TOLERANCE>.md and no plots. Parts whose protection is refused
# (the fit cannot meet its share of the tolerance) are listed with the reason.
#
# Usage: scripts/bench-detect.sh WORK_DIR
#   MESHMARK=path/to/meshmark (default build/daemon/meshmark), MESHES=dir,
#   LIST="fandisk.off bracket-3.stl ..." (default: the nine CAD parts of the compression benchmark),
#   ATTACKS="none noise-0.001 ..." (default: all below), WORKERS=2,
#   TOLERANCE=0.001 (compression.tolerance of the protected copies; default the config's, 0.005),
#   MAX_VERTICES=20000 (with TOLERANCE: compression.max_vertices and watermark.max_vertices; the
#   results file is then detect-tolerance-<TOLERANCE>-<MAX_VERTICES>.md).
# WORK_DIR/setup (home, copies, suspects) is made once and reused; each run detects in a fresh
# copy of the home (WORK_DIR/run-<n>), so builds are compared on the same copies and suspects.
set -euo pipefail
BENCH_ENV="MESHMARK MESHES LIST ATTACKS WORKERS TOLERANCE MAX_VERTICES"
. "$(dirname "$0")/bench-results.sh"
if [ -n "${TOLERANCE:-}" ] && [ -n "${MAX_VERTICES:-}" ]; then
  bench_results "detect-tolerance-$TOLERANCE-$MAX_VERTICES" \
    "Detection after attacks at compression.tolerance $TOLERANCE, up to $MAX_VERTICES control vertices" "$@"
elif [ -n "${TOLERANCE:-}" ]; then
  bench_results "detect-tolerance-$TOLERANCE" "Detection after attacks at compression.tolerance $TOLERANCE" "$@"
else
  bench_results detect "Detection after attacks: verdicts over the shared CAD parts" "$@"
fi
. "$(dirname "$0")/bench-homes.sh"
here="$(cd "$(dirname "$0")/.." && pwd)"
MM=$(realpath "${MESHMARK:-$here/build/daemon/meshmark}")
MESHES=$(realpath "${MESHES:-$here/../shared/data/meshes}")
W=${1:?usage: bench-detect.sh WORK_DIR}
LIST=${LIST:-"fandisk.off bracket-3.stl blade.stl rocker.stl abc5.stl abc6.stl abc7.stl abc8.stl abc9.stl"}
ALL_ATTACKS="none stream format-stl reorder similarity noise-0.001 noise-0.0025 noise-0.005 quantize-10 quantize-8
  smooth-5 smooth-10 simplify-0.5 simplify-0.1 remesh-0.01 remesh-0.02 wrap-0.005 crop-0.8 crop-0.5
  chain-half average-2 average-3"
ATTACKS=${ATTACKS:-$ALL_ATTACKS}
WORKERS=${WORKERS:-2}
customers=(alice bob carol)
mkdir -p "$W"
W=$(realpath "$W")

config() {  # config DIR
  local compression=""
  [ -z "${TOLERANCE:-}" ] || compression=", \"compression\": {\"tolerance\": $TOLERANCE}"
  [ -z "${TOLERANCE:-}" ] || [ -z "${MAX_VERTICES:-}" ] || compression=", \"compression\": {\"tolerance\": $TOLERANCE,
 \"max_vertices\": $MAX_VERTICES}, \"watermark\": {\"max_vertices\": $MAX_VERTICES}"
  cat >"$1/meshmarkd.json" <<EOF
{"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": $WORKERS, "log_level": "warn",
 "output_format": "off"$compression}
EOF
}

# attack NAME IN OUT: one named attack of the list above.
attack() {
  local name=$1 in=$2 out=$3 kind=${1%%-*} strength=${1#*-}
  case "$kind" in
    none) cp "$in" "$out" ;;
    format) "$MM" attack noise -A 0 "$in" "$out" >/dev/null ;;
    reorder) "$MM" attack reorder --seed 7 "$in" "$out" >/dev/null ;;
    similarity) "$MM" attack similarity --scale 25.4 --rotate 30 --shift 0.5 0 0 "$in" "$out" >/dev/null ;;
    noise) "$MM" attack noise -A "$strength" --seed 3 "$in" "$out" >/dev/null ;;
    quantize) "$MM" attack quantize --bits "$strength" "$in" "$out" >/dev/null ;;
    smooth) "$MM" attack smooth -n "$strength" --lambda 0.5 "$in" "$out" >/dev/null ;;
    simplify) "$MM" attack simplify --keep "$strength" "$in" "$out" >/dev/null ;;
    remesh) "$MM" attack remesh --edge "$strength" "$in" "$out" >/dev/null ;;
    wrap) "$MM" attack wrap --alpha "$strength" "$in" "$out" >/dev/null ;;
    crop) "$MM" attack crop --keep "$strength" "$in" "$out" >/dev/null ;;
    chain)  # three attacks at half strength: remeshing at 1 %, noise at 0.25 %, simplification to a half
      "$MM" attack remesh --edge 0.01 "$in" "$out.1.off" >/dev/null
      "$MM" attack noise -A 0.0025 --seed 4 "$out.1.off" "$out.2.off" >/dev/null
      "$MM" attack simplify --keep 0.5 "$out.2.off" "$out" >/dev/null
      rm -f "$out.1.off" "$out.2.off" ;;
    *) echo "bench-detect: unknown attack $name" >&2; exit 2 ;;
  esac
}

if [ ! -f "$W/setup/ready" ]; then
  S="$W/setup"
  bench_protect "$S" "$MESHES" "$LIST" "${customers[@]}"
  i=0
  for p in $LIST; do
    stem=${p%.*}
    leaker=${customers[$((i % 3))]} other=${customers[$(((i + 1) % 3))]} third=${customers[$(((i + 2) % 3))]}
    i=$((i + 1))
    decoded=$(ls "$S/out/$leaker/$stem"-*.off 2>/dev/null || true)
    [ -n "$decoded" ] || continue  # refused: reported from the protect jobs below
    for a in $ATTACKS; do
      out="$S/suspects/$stem--$a--$leaker.off"
      case "$a" in
        stream) cp "$(ls "$S/out/$leaker/$stem"-*.mmc)" "${out%.off}.mmc" ;;
        format-stl) attack "$a" "$decoded" "${out%.off}.stl" ;;
        average-2) "$MM" attack average "$decoded" "$(ls "$S/out/$other/$stem"-*.off)" \
                     "$S/suspects/$stem--$a--$leaker+$other.off" >/dev/null ;;
        average-3) "$MM" attack average "$decoded" "$(ls "$S/out/$other/$stem"-*.off)" \
                     "$(ls "$S/out/$third/$stem"-*.off)" "$S/suspects/$stem--$a--$leaker+$other+$third.off" >/dev/null ;;
        *) attack "$a" "$decoded" "$out" ;;
      esac
    done
    # Innocent suspects: the unmarked original, attacked as a leak would be, and another tessellation.
    orig="$MESHES/$p"
    "$MM" attack noise -A 0.001 --seed 5 "$orig" "$S/suspects/$stem--innocent-noise--nobody.off" >/dev/null
    "$MM" attack remesh --edge 0.01 "$orig" "$S/suspects/$stem--innocent-remesh--nobody.off" >/dev/null
    "$MM" attack smooth -n 10 "$orig" "$S/suspects/$stem--innocent-smooth--nobody.off" >/dev/null
    "$MM" attack subdivide --linear -L 1 "$orig" "$S/suspects/$stem--innocent-split--nobody.off" >/dev/null
  done
  touch "$S/ready"
fi

bench_detect_run "$W"
"$MM" jobs list --home "$R/home" --kind detect --json --limit 100000 >"$R/jobs.json"
echo "run $R: $(cat "$R/run.txt")"
echo "detect jobs: wall ${wall} s, CPU user ${user} s, peak RSS $((rss / 1024)) MB, $WORKERS workers"
plots=; [ -n "${TOLERANCE:-}" ] || ! bench_writes_docs || plots=1
python3 - "$R" "$W/setup/home" "$MM" "$WORKERS" "$here" "$plots" <<'PY'
import json, os, subprocess, sys, collections
run, home, mm, workers = sys.argv[1:5]
plots = bool(sys.argv[6])
dets = json.load(open(run + "/detections.json"))
customers = {c["id"]: c["name"] for c in json.loads(subprocess.check_output([mm, "customer", "list", "--home", home, "--json"]))}
rows = []
for d in dets:
    stem, attack, truth = d["suspect_name"].rsplit(".", 1)[0].split("--")
    expected = set(truth.split("+")) - {"nobody"}
    named = {customers.get(a["customer_id"]) for a in d["details"].get("attributed", [])}
    p = d["details"].get("best_neg_log10_corrected_p", 0)
    if named - expected: outcome = "WRONG"
    elif not named and not expected: outcome = "ok"
    elif not named: outcome = "missed"
    elif named == expected: outcome = "traced"
    else: outcome = "partial"
    rows.append((stem, attack, truth, d["verdict"], "+".join(sorted(named)) or "-", p, d.get("resync_method") or "-",
                 d["details"].get("seconds", 0.0), outcome))
rows.sort()
print("%-10s %-18s %-18s %-18s %-18s %9s %-12s %7s %s" % ("part", "attack", "leaker", "verdict", "named", "-log10p", "resync", "seconds", "outcome"))
for r in rows:
    print("%-10s %-18s %-18s %-18s %-18s %9.1f %-12s %7.2f %s" % r)
by = collections.OrderedDict()
for r in rows:
    by.setdefault(r[1], []).append(r)
print()
print("%-18s %7s %6s %6s  %s" % ("attack", "traced", "wrong", "tried", "median -log10 p"))
for a, rs in sorted(by.items()):
    traced = sum(r[8] == "traced" for r in rs)
    wrong = sum(r[8] == "WRONG" for r in rs)
    ps = sorted(r[5] for r in rs)
    print("%-18s %7d %6d %6d  %.1f" % (a, traced, wrong, len(rs), ps[len(ps) // 2]))
print()
print("%-12s %6s %8s %8s  (wall seconds of one detection, %s workers at once)" % ("resync", "count", "median", "max", workers))
paths = {}
for r in rows:
    paths.setdefault(r[6], []).append(r[7])
for path, secs in sorted(paths.items()):
    secs.sort()
    print("%-12s %6d %8.2f %8.2f" % (path, len(secs), secs[len(secs) // 2], secs[-1]))
leaks = [r for r in rows if r[2] != "nobody"]
innocent = [r for r in rows if r[2] == "nobody"]
print()
# The mark's own cost on each part's issued copies (the protect jobs' results): how far the
# decoded copy's vertices lie from the unmarked surface's, over the diagonal (median of the copies).
protects = json.loads(subprocess.check_output([mm, "jobs", "list", "--home", home, "--kind", "protect", "--json",
                                               "--limit", "100000"]))["jobs"]
cost = {}
for j in protects:
    r = j.get("result") or {}
    if isinstance(r, str):
        r = json.loads(r or "{}")
    if "output" in r:
        cost.setdefault(os.path.basename(r["output"]).rsplit("-", 1)[0], []).append(r)
print("%-10s %8s %8s %8s %8s %10s %10s  (median over the part's copies; %% of the diagonal)" % (
    "part", "control", "stream B", "fit %", "strength", "mark max %", "mark RMS %"))
for part, rs in sorted(cost.items()):
    med = lambda k: sorted(x.get(k, 0) for x in rs)[len(rs) // 2]
    print("%-10s %8d %8d %8.3f %8.4f %10.3f %10.3f" % (part, med("control_vertices"), med("stream_bytes"),
                                                       100 * med("fit_hausdorff"), med("strength"),
                                                       100 * med("mark_max"), 100 * med("mark_rms")))
refused = {}
for j in protects:
    if j.get("state") == "discarded" and j.get("errors"):
        why = j["errors"][-1]["error"]
        refused.setdefault(why.split(":")[0], why)
for part, why in sorted(refused.items()):
    print("refused   %s" % why)
# -log10 p against strength per attack (as the paper's Figure 8), one curve per part, with the
# threshold: docs/results/detect-<attack>.png.
results = os.path.join(sys.argv[5], "docs", "results")
labels = {"noise": "uniform noise (x largest side)", "quantize": "bits", "smooth": "smoothing steps (lambda 0.5)",
          "simplify": "edges kept", "remesh": "edge length (x diagonal)", "crop": "share of the longest side kept"}
for family, x_label in (labels.items() if plots else []):
    points = [(r[0], float(r[1].split("-", 1)[1]), min(r[5], 100.0)) for r in rows if r[1].startswith(family + "-")]
    if not points:
        continue
    if family in ("noise", "smooth"):
        points += [(r[0], 0.0, min(r[5], 100.0)) for r in rows if r[1] == "none"]
    xs = sorted({x for _, x, _ in points})
    table = os.path.join(run, "detect-%s.tsv" % family)
    with open(table, "w") as f:
        for part, x, y in sorted(points):
            f.write("%s\t%g\t%g\n" % (part, x, y))
        for x in xs:
            f.write("p = 1e-9\t%g\t9\n" % x)
    os.makedirs(results, exist_ok=True)
    subprocess.check_call([mm, "plot", table, os.path.join(results, "detect-%s.png" % family), "--title",
                           "detection after " + family, "--x-label", x_label, "--y-label", "-log10 corrected p",
                           "--y-max", "100"], stdout=subprocess.DEVNULL)
print("traced %d of %d leaks (every leaker named, no one else); wrong customers %d; innocent suspects attributed %d of %d" % (
    sum(r[8] == "traced" for r in leaks), len(leaks), sum(r[8] == "WRONG" for r in rows),
    sum(r[4] != "-" for r in innocent), len(innocent)))
PY
