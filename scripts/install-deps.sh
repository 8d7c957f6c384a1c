#!/usr/bin/env bash
# Install the Debian 12 packages sooc3d builds and tests against.
# Only packages that are missing are installed; the script is safe to re-run.
set -euo pipefail

PKGS=(
  build-essential cmake pkg-config git
  libopenblas-dev liblapacke-dev
  libpng-dev libjpeg62-turbo-dev libyaml-dev libsqlite3-dev sqlite3 libmatio-dev
  libopenni2-dev libopenni2-0
  libfreenect-dev libfreenect-bin
  libv4l-dev
  libcamera-dev
  libopencv-dev libopencv-contrib-dev libceres-dev
  libopenmpi-dev openmpi-bin
  python3 python3-numpy python3-torch
  python3-yaml python3-opencv
  clang libclang-rt-14-dev
  liblz4-dev libzstd-dev libbz2-dev python3-rosbag libwebsockets-dev chromium
)

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
else
  echo "install-deps: installing ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The reference MCAP library the log tests write and read MCAP files with
# (tests/logs/npm: package.json and package-lock.json pin it; node_modules is
# not committed). Without Node.js or the npm registry those tests skip.
NPM_DIR="$(cd "$(dirname "$0")/.." && pwd)/tests/logs/npm"
if command -v npm >/dev/null 2>&1; then
  if [ -d "$NPM_DIR/node_modules/@mcap/core" ]; then
    echo "install-deps: @mcap/core present in $NPM_DIR"
  else
    (cd "$NPM_DIR" && npm ci --no-audit --no-fund) || echo "install-deps: npm ci in $NPM_DIR failed; test_logs_npm and the @mcap/core checks will skip"
  fi
else
  echo "install-deps: no npm (apt-get install npm); test_logs_npm and the @mcap/core checks will skip"
fi
