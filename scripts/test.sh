#!/usr/bin/env bash
# Run every test: installs missing packages, then builds and tests
# (Release with OpenMP, and ASan/UBSan without OpenMP), with -Werror; then the
# threaded parts (the model's task pool, OpenMP regions, the node's threads)
# once more under ASan/UBSan with OpenMP on.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
JOBS=$(nproc)
run() {
  local dir=$1 filter=$2; shift 2
  cmake -S . -B "$dir" -DSOOC_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j"$JOBS"
  (cd "$dir" && ctest --output-on-failure -j"$JOBS" ${filter:+-R "$filter"})
}
run build-ci-omp "" -DCMAKE_BUILD_TYPE=Release -DSOOC_OPENMP=ON -DSOOC_BUILD_FUZZ=ON
run build-ci-asan "" -DCMAKE_BUILD_TYPE=Debug -DSOOC_OPENMP=OFF -DSOOC_ASAN=ON -DSOOC_BUILD_BENCH=OFF -DSOOC_BUILD_FUZZ=ON
run build-ci-asan-omp "^test_(model|nn|eval|render|node_model|node_e2e)" -DCMAKE_BUILD_TYPE=Debug -DSOOC_OPENMP=ON \
  -DSOOC_ASAN=ON -DSOOC_BUILD_BENCH=OFF
echo "all tests passed"
