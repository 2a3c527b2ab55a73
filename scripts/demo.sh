#!/usr/bin/env bash
# The main job, end to end, on sample parts the project makes itself (no ../shared needed):
# installs what is missing, builds, starts the meshmarkd daemon on a temporary home and drop
# folder, protects three mesh parts and a STEP part for customers alice and bob (tessellate the
# STEP part, compress, watermark, write the .mmc stream and the decoded mesh), leaks bob's decoded
# copy and alice's copy of the STEP part with noise, drops them and an unmarked original into
# detect/ and prints the verdicts, and the signed evidence package the daemon writes
# for the attribution (verified); a PDM system's round trip over the HTTP API (a token, an upload,
# protect for carol sent twice with one Idempotency-Key, polled, the copy downloaded); then stops
# the daemon with SIGTERM (drain).
# DEMO_DIR=folder keeps everything there (default: a fresh temporary folder, printed at the end).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target meshmark meshmarkd >/dev/null
BUILD=${BUILD_DIR:-build}
MM=$(realpath "$BUILD/daemon/meshmark")
MMD=$(realpath "$BUILD/daemon/service/meshmarkd")
if [ -n "${DEMO_DIR:-}" ]; then
  rm -rf "$DEMO_DIR" && mkdir -p "$DEMO_DIR"
  D=$(realpath "$DEMO_DIR")
else
  D=$(mktemp -d /tmp/meshmark-demo.XXXXXX)
fi
mkdir -p "$D/drop" "$D/out" "$D/parts"
pid=""
cleanup() { [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null && kill -TERM "$pid" && wait "$pid" || true; }
trap cleanup EXIT

# wait_for DESCRIPTION SECONDS COMMAND...: polls until COMMAND succeeds.
wait_for() {
  local what=$1 secs=$2
  shift 2
  for _ in $(seq $((secs * 5))); do
    "$@" && return 0
    kill -0 "$pid" 2>/dev/null || { echo "meshmarkd exited; log:"; cat "$D/meshmarkd.log"; exit 1; }
    sleep 0.2
  done
  echo "timed out waiting for $what; log:"
  cat "$D/meshmarkd.log"
  exit 1
}
count() { find "$1" -maxdepth 1 -type f ! -name '*.json' ! -name '.*' 2>/dev/null | wc -l; }

echo "== home, customers, configuration ($D)"
"$MM" init --home "$D/home"
"$MM" customer add alice --home "$D/home"
"$MM" customer add bob --home "$D/home"
"$MM" customer add carol --home "$D/home"
cat >"$D/meshmarkd.json" <<EOF
{
  "home": "home", "drop_dir": "drop", "output_dir": "out",
  "workers": 2, "poll_interval_ms": 200, "settle_ms": 500,
  "output_format": "stl",
  "evidence": {"auto": true},
  "http": {"listen": "unix:$D/api.sock"},
  "log_file": "meshmarkd.log"
}
EOF

echo "== sample parts"
parts=(chamfered_block plate_with_holes flanged_cylinder)
for p in "${parts[@]}"; do
  "$MM" sample "$p" "$D/parts/$p.off"
done
# A CAD part as a PDM vault holds it: STEP, written by OpenCASCADE, tessellated at intake.
"$MM" sample drilled_block "$D/parts/drilled_block.step"
"$MM" info "$D/parts/drilled_block.step"

echo "== start meshmarkd"
"$MMD" --config "$D/meshmarkd.json" &
pid=$!
started() { grep -qs "meshmarkd started" "$D/meshmarkd.log"; }
wait_for "start-up" 30 started

echo "== drop the parts into protect/alice and protect/bob"
for who in alice bob; do
  mkdir -p "$D/drop/protect/$who"
  for p in "${parts[@]}"; do
    # Write under a temporary name, then rename: the daemon takes the file at the rename.
    cp "$D/parts/$p.off" "$D/drop/protect/$who/.$p.off.tmp"
    mv "$D/drop/protect/$who/.$p.off.tmp" "$D/drop/protect/$who/$p.off"
  done
  cp "$D/parts/drilled_block.step" "$D/drop/protect/$who/.drilled_block.step.tmp"
  mv "$D/drop/protect/$who/.drilled_block.step.tmp" "$D/drop/protect/$who/drilled_block.step"
done
done_both() { [ "$(count "$D/drop/done/protect/alice")" -eq 4 ] && [ "$(count "$D/drop/done/protect/bob")" -eq 4 ]; }
wait_for "8 protect jobs" 900 done_both
if [ -d "$D/drop/failed" ] && [ -n "$(find "$D/drop/failed" -type f)" ]; then
  echo "some jobs failed:"; find "$D/drop/failed" -name '*.json' -exec cat {} \;; exit 1
fi
python3 - "$D/drop/done/protect" <<'EOF'
import json, pathlib, sys
for f in sorted(pathlib.Path(sys.argv[1]).glob("*/*.json")):
    r = json.loads(f.read_text())["result"]
    print(f"{r['customer']:>5} {f.stem:<22} {r['vertices']:>5} vertices -> {r['control_vertices']:>4} control"
          f" vertices, stream {r['stream_bytes']:>5} bytes, decoded {r['decoded_vertices']:>6} vertices, payload {r['payload']}")
EOF
ls -l "$D/out/bob"

echo "== bob's decoded flanged_cylinder leaks, with noise (0.0005 of the part's size)"
leak=$(ls "$D"/out/bob/flanged_cylinder-*.stl)
"$MM" attack noise "$leak" "$D/parts/leak.stl" --amplitude 0.0005 --seed 7
echo "== alice's copy of the STEP part leaks as an STL file, with noise"
"$MM" attack noise "$(ls "$D"/out/alice/drilled_block-*.stl)" "$D/parts/leak-step.stl" --amplitude 0.0005 --seed 8
echo "== ... and, as a control, the unmarked original flanged_cylinder"
mkdir -p "$D/drop/detect"
cp "$D/parts/leak.stl" "$D/drop/detect/.leak.stl.tmp"
mv "$D/drop/detect/.leak.stl.tmp" "$D/drop/detect/leak.stl"
cp "$D/parts/flanged_cylinder.off" "$D/drop/detect/.original.off.tmp"
mv "$D/drop/detect/.original.off.tmp" "$D/drop/detect/original.off"
cp "$D/parts/leak-step.stl" "$D/drop/detect/.leak-step.stl.tmp"
mv "$D/drop/detect/.leak-step.stl.tmp" "$D/drop/detect/leak-step.stl"
detected() { [ -f "$D/drop/done/detect/leak.stl.json" ] && [ -f "$D/drop/done/detect/original.off.json" ] &&
             [ -f "$D/drop/done/detect/leak-step.stl.json" ]; }
wait_for "the detect jobs" 300 detected

echo "== verdicts"
python3 - "$D/drop/done/detect" <<'EOF'
import json, sys
ok = True
for name, expect in (("leak.stl", "bob"), ("leak-step.stl", "alice"), ("original.off", None)):
    r = json.load(open(f"{sys.argv[1]}/{name}.json"))["result"]
    print(f"{name}: {r['verdict']}")
    if r["verdict"] == "attributed":
        print(f"  customer: {r['customer']}  (copy {r['copy_id']}, payload {r['decoded_payload']})")
    if "p_value" in r:
        print(f"  p-value (Bonferroni over {r['copies_tried']} copies): {r['p_value']:.3g}"
              f"  (-log10 p = {r['neg_log10_p']:.1f})")
    print(f"  found by: {r['match']}; resynchronised as '{r.get('resync_method')}',"
          f" residual {r.get('resync_residual', 0):.2g} of the part's diagonal")
    ok = ok and r.get("customer") == expect
sys.exit(0 if ok else 1)
EOF

echo "== evidence package for the legal team (docs/evidence.md)"
packaged() { ls "$D"/out/evidence/*/statement.dsse.json >/dev/null 2>&1; }
wait_for "the evidence package" 120 packaged
pkg=$(dirname "$(ls "$D"/out/evidence/*/statement.dsse.json | head -1)")
ls "$pkg"
"$BUILD/daemon/meshmark" evidence pubkey --home "$D/home" >"$D/signing-public-key.txt"
"$BUILD/daemon/meshmark" verify "$pkg" --pubkey "$D/signing-public-key.txt" --file "$D/parts/leak.stl" | tail -n 2
echo "open $pkg/report.html in a browser"

echo "== a PDM system over the HTTP API (docs/api.md): carol's copy of plate_with_holes"
token=$("$MM" token create pdm --role submit --json --home "$D/home" | python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')
api() { curl -sS --unix-socket "$D/api.sock" -H "Authorization: Bearer $token" "$@"; }
sha=$(api --data-binary @"$D/parts/plate_with_holes.off" 'http://meshmark/v1/parts?name=plate_with_holes.off' |
      python3 -c 'import json,sys; print(json.load(sys.stdin)["sha256"])')
body="{\"part\": {\"sha256\": \"$sha\", \"name\": \"plate_with_holes.off\"}, \"customers\": [\"carol\"]}"
submit() { api -H 'Idempotency-Key: "demo-carol-1"' -H 'Content-Type: application/json' -d "$body" http://meshmark/v1/jobs/protect; }
job=$(submit | python3 -c 'import json,sys; print(json.load(sys.stdin)["jobs"][0]["id"])')
again=$(submit | python3 -c 'import json,sys; print(json.load(sys.stdin)["jobs"][0]["id"])')
echo "job $job; the same request again answers job $again (no second copy)"
state() { api "http://meshmark/v1/jobs/$job" | python3 -c 'import json,sys; print(json.load(sys.stdin)["state"])'; }
finished() { [[ "$(state)" =~ ^(succeeded|failed|cancelled)$ ]]; }
wait_for "carol's protect job" 300 finished
echo "job $job: $(state)"
api -o "$D/carol-plate_with_holes.stl" "http://meshmark/v1/jobs/$job/copy"
ls -l "$D/carol-plate_with_holes.stl"
api http://meshmark/v1/queue; echo
[ "$(state)" = succeeded ] && [ "$job" = "$again" ]

echo "== stop meshmarkd (SIGTERM: finish running jobs, then exit)"
kill -TERM "$pid"
status=0
wait "$pid" || status=$?
pid=""
echo "meshmarkd exited with status $status"
tail -n 3 "$D/meshmarkd.log"
echo "everything is in $D (meshmark detections --home $D/home)"
[ "$status" -eq 0 ]
