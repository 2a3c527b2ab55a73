#!/usr/bin/env bash
# The offline walk-through, files only (no store, no daemon): a CAD-like sample part is compressed
# into a control-polyhedron stream, watermarked for two customers, Bob's copy is decoded to a
# surface and leaks with noise, and extraction against each customer's copy record says whose it is.
# Works from a clean clone: installs what is missing, builds only the `meshmark` binary.
# DEMO_DIR (default out/demo-offline) holds every file it makes; BUILD_DIR as for scripts/build.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target meshmark >/dev/null
MM=${BUILD_DIR:-build}/daemon/meshmark
OUT=${DEMO_DIR:-out/demo-offline}
rm -rf "$OUT" && mkdir -p "$OUT"
run() { echo "\$ meshmark $*" | sed "s#$OUT/##g"; "$MM" "$@"; }

echo "== 1. a sample part, compressed to a subdivision control polyhedron"
run sample flanged-cylinder "$OUT/part.off"
run compress "$OUT/part.off" "$OUT/part.mmc"

echo; echo "== 2. one secret key per customer (mode 0600; the key is never printed)"
run keygen "$OUT/alice.key"
run keygen "$OUT/bob.key"

echo; echo "== 3. one watermarked stream per customer, each with its copy record"
run embed "$OUT/part.mmc" "$OUT/alice.key" "$OUT/part-alice.mmc" --message alice
run embed "$OUT/part.mmc" "$OUT/bob.key" "$OUT/part-bob.mmc" --message bob

echo; echo "== 4. Bob decodes his copy to a surface, which leaks slightly noisy"
run decompress "$OUT/part-bob.mmc" "$OUT/bob-surface.off"
run attack noise "$OUT/bob-surface.off" "$OUT/leak.off" --amplitude 0.0005 --seed 7

echo; echo "== 5. the leak examined against each customer's copy record"
found=""
for who in alice bob; do
  run extract "$OUT/part.mmc" "$OUT/leak.off" "$OUT/$who.key" --record "$OUT/part-$who.mmc.mmrec.json" | sed 's/^/   /'
  "$MM" extract "$OUT/part.mmc" "$OUT/leak.off" "$OUT/$who.key" --record "$OUT/part-$who.mmc.mmrec.json" --json \
    > "$OUT/verdict-$who.json"
  verdict=$(sed -n 's/^  "verdict": "\(.*\)",*$/\1/p' "$OUT/verdict-$who.json")
  [ "$verdict" = "watermark present" ] && found="$found $who"
done
echo
if [ "$found" = " bob" ]; then
  echo "RESULT: the leak is Bob's copy (Alice's record finds no watermark). Files in $OUT/."
else
  echo "RESULT: unexpected attribution: '${found# }' (see $OUT/verdict-*.json)" >&2
  exit 1
fi
