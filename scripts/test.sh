#!/usr/bin/env bash
# Run every test: installs missing packages, then builds and tests twice
# (Release with OpenMP, and ASan/UBSan without OpenMP), with -Werror.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
JOBS=$(nproc)
run() {
  local dir=$1; shift
  cmake -S . -B "$dir" -DSOOC_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j"$JOBS"
  (cd "$dir" && ctest --output-on-failure -j"$JOBS")
}
run build-ci-omp -DCMAKE_BUILD_TYPE=Release -DSOOC_OPENMP=ON -DSOOC_BUILD_FUZZ=ON
run build-ci-asan -DCMAKE_BUILD_TYPE=Debug -DSOOC_OPENMP=OFF -DSOOC_ASAN=ON -DSOOC_BUILD_BENCH=OFF -DSOOC_BUILD_FUZZ=ON
echo "all tests passed"
