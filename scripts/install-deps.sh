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
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
