# Sourced by the scripts/bench-*.sh: `bench_results NAME TITLE "$@"` runs the calling script again
# with its standard output also kept and, when it succeeds, rewrites docs/results/NAME.md with the
# title, the command (and the environment variables in BENCH_ENV that are set), the commit, the
# machine's cores and CPU, and the output. A failed run leaves the previous results file in place.
# MESHMARK_BENCH_INNER=1 set by hand runs the script alone: nothing under docs/ is rewritten, and
# pictures the script draws are written only where bench_writes_docs says so.
bench_writes_docs() { [ -n "${MESHMARK_BENCH_WRITE:-}" ]; }
bench_results() {
  [ -n "${MESHMARK_BENCH_INNER:-}" ] && return 0
  local name=$1 title=$2
  shift 2
  local root log status command var
  root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
  log=$(mktemp)
  command="scripts/$(basename "$0")"
  for var in ${BENCH_ENV:-}; do
    [ -z "${!var:-}" ] || command="$var=$(printf '%q' "${!var}") $command"
  done
  [ $# -eq 0 ] || command="$command$(printf ' %q' "$@")"
  set +e
  MESHMARK_BENCH_INNER=1 MESHMARK_BENCH_WRITE=1 "$0" "$@" | tee "$log"
  status=${PIPESTATUS[0]}
  set -e
  if [ "$status" -eq 0 ]; then
    mkdir -p "$root/docs/results"
    {
      echo "# $title"
      echo
      echo "Written by \`$command\`; do not edit by hand."
      echo
      echo "- commit: $(git -C "$root" describe --always --dirty 2>/dev/null || echo unknown)"
      echo "- machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
      echo "- run: $(date -u '+%Y-%m-%d %H:%M UTC')"
      echo
      echo '```text'
      cat "$log"
      echo '```'
    } >"$root/docs/results/$name.md.tmp"
    mv "$root/docs/results/$name.md.tmp" "$root/docs/results/$name.md"
    echo "results: docs/results/$name.md" >&2
  fi
  rm -f "$log"
  exit "$status"
}
