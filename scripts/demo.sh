#!/usr/bin/env bash
# The main job on sample data the project makes itself: installs what is missing, builds, then
# generates a CAD-like part, watermarks it for two customers, "leaks" one copy with noise, and
# shows that extraction names the right customer and clears the other.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target meshmark >/dev/null
MM=${BUILD_DIR:-build}/daemon/meshmark
OUT=${DEMO_DIR:-out/demo}
rm -rf "$OUT" && mkdir -p "$OUT"

echo "== sample part"
$MM sample flanged-cylinder "$OUT/part.off"
$MM info "$OUT/part.off"

echo "== keys for two customers"
$MM keygen "$OUT/alice.key"
$MM keygen "$OUT/bob.key"

echo "== one watermarked copy each"
$MM embed "$OUT/part.off" "$OUT/alice.key" "$OUT/part-alice.off" --message "copy:alice"
$MM embed "$OUT/part.off" "$OUT/bob.key" "$OUT/part-bob.off" --message "copy:bob"

echo "== bob's copy leaks, slightly noisy"
$MM attack noise "$OUT/part-bob.off" "$OUT/leak.off" --amplitude 0.0005 --seed 7

echo "== extraction against each customer's copy record"
for who in alice bob; do
  $MM extract "$OUT/part.off" "$OUT/leak.off" "$OUT/$who.key" --record "$OUT/part-$who.off.mmrec.json" \
    > "$OUT/verdict-$who.json"
  echo "$who: $(cat "$OUT/verdict-$who.json" | tr -d '\n' | sed 's/  */ /g')"
done
