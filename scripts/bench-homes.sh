# Sourced by the detection benchmarks: a home whose parts are protected once (WORK_DIR/setup) and
# fresh runs that detect the setup's suspects in a copy of that home, so builds and budgets are
# compared on the same copies and suspects. The caller sets MM (the meshmark binary) and defines
# `config DIR`, which writes DIR/meshmarkd.json for a home at DIR/home.

# bench_protect SETUP MESHES "PARTS" CUSTOMER...: a new home in SETUP with the customers and every
# part protected for each of them by `meshmark run`; an empty SETUP/suspects for the caller.
bench_protect() {
  local setup=$1 meshes=$2 parts=$3 p who
  shift 3
  rm -rf "$setup"
  mkdir -p "$setup/drop" "$setup/out" "$setup/suspects"
  "$MM" init --home "$setup/home" >/dev/null
  for who in "$@"; do "$MM" customer add "$who" --home "$setup/home" >/dev/null; done
  config "$setup"
  for p in $parts; do
    for who in "$@"; do
      "$MM" submit protect --config "$setup/meshmarkd.json" --customer "$who" "$meshes/$p" >/dev/null
    done
  done
  # A part the fit cannot bring within its tolerance fails its jobs; the caller reports them.
  (cd "$setup" && "$MM" run --until-empty --no-drops --config meshmarkd.json >/dev/null) || true
}

# bench_new_run WORK_DIR: sets R to a new WORK_DIR/run-<n> holding a copy of WORK_DIR/setup's home,
# its configuration, and every suspect of WORK_DIR/setup/suspects submitted for detection.
bench_new_run() {
  local n=1
  while [ -e "$1/run-$n" ]; do n=$((n + 1)); done
  R="$1/run-$n"
  mkdir -p "$R/drop" "$R/out"
  cp -a "$1/setup/home" "$R/home"
  config "$R"
  (cd "$R" && "$MM" submit detect --config meshmarkd.json "$1/setup/suspects"/* >/dev/null)
}

# bench_detect_run WORK_DIR: a new run (bench_new_run) whose queue `meshmark run` works off under
# /usr/bin/time; sets R, wall and user (seconds) and rss (kB), and writes R/detections.json.
bench_detect_run() {
  bench_new_run "$1"
  /usr/bin/time -f "%e %U %M" -o "$R/time" bash -c "cd '$R' && '$MM' run --until-empty --no-drops --config meshmarkd.json" \
    >"$R/run.txt" 2>"$R/run.log" || true
  "$MM" detections --home "$R/home" --json --limit 100000 >"$R/detections.json"
  # The last line: time puts "Command exited with non-zero status N" first when a job failed.
  read -r wall user rss < <(tail -n 1 "$R/time")
}
