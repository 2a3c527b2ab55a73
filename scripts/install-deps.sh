#!/usr/bin/env bash
# Installs the Debian packages meshmark builds and tests with, only those missing.
# Everything comes from Debian 12's archive; nothing is downloaded from elsewhere.
set -euo pipefail
PKGS=(
  build-essential cmake pkg-config
  libeigen3-dev libopenmesh-dev libosd-dev libsqlite3-dev sqlite3
  nlohmann-json3-dev libspdlog-dev libcli11-dev libsodium-dev zlib1g-dev
  libcgal-dev libboost-dev libspectra-dev libgtest-dev libgmock-dev libbenchmark-dev
  lib3mf-dev libtinygltf-dev libdraco-dev libocct-data-exchange-dev libocct-modeling-algorithms-dev libpng-dev draco python3 jq time openssl curl nginx-light postgresql-15 libpq-dev chromium prometheus clang libclang-rt-14-dev
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
