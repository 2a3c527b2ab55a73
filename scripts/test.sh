#!/usr/bin/env bash
# The one command that installs what is missing, builds, and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
if [ ! -d ../shared/data/meshes ]; then
  echo "NOTE: ../shared/data/meshes is absent: tests on the shared real meshes will report it and fail." >&2
fi
cd "${BUILD_DIR:-build}"
ctest --output-on-failure -j "${JOBS:-$(nproc)}" "$@"
