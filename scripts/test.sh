#!/usr/bin/env bash
# Run every test: installs missing packages, then builds and tests
# (Release with OpenMP, and ASan/UBSan without OpenMP), with -Werror; then the
# threaded parts (the model's task pool, OpenMP regions, the node's threads)
# once more under ASan/UBSan with OpenMP on, and the node and table tests under
# ThreadSanitizer.
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
# The numerics tests once more under every OpenBLAS kernel family this CPU can
# run (Debian's OpenBLAS picks one at run time; OPENBLAS_CORETYPE forces it), so
# that a test that depends on the BLAS kernel fails on any machine, not only on
# CPUs whose default kernel happens to suit it (docs/engine.md "Determinism contract").
coretypes=()
flags=" $(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null | cut -d: -f2) "
has() { [[ "$flags" == *" $1 "* ]]; }
has pni && coretypes+=(Prescott)
has sse4_2 && coretypes+=(Nehalem)
has avx && coretypes+=(Sandybridge)
has avx2 && has fma && coretypes+=(Haswell Zen)
has avx512f && coretypes+=(SkylakeX Cooperlake)
[ ${#coretypes[@]} -gt 0 ] || echo "test.sh: no x86 OpenBLAS core types on this CPU; the per-kernel pass is skipped"
for ct in "${coretypes[@]}"; do
  echo "== numerics tests with OPENBLAS_CORETYPE=$ct"
  (cd build-ci-omp && OPENBLAS_CORETYPE=$ct ctest --output-on-failure -j"$JOBS" -R '^test_(nn|model)_')
done
run build-ci-asan "" -DCMAKE_BUILD_TYPE=Debug -DSOOC_OPENMP=OFF -DSOOC_ASAN=ON -DSOOC_BUILD_BENCH=OFF -DSOOC_BUILD_FUZZ=ON
run build-ci-asan-omp "^test_(model|nn|eval|render|node_model|node_e2e)" -DCMAKE_BUILD_TYPE=Debug -DSOOC_OPENMP=ON \
  -DSOOC_ASAN=ON -DSOOC_BUILD_BENCH=OFF
# ThreadSanitizer over the node's and the shm table's threads. OpenMP off and
# one OpenBLAS thread: neither libgomp nor OpenBLAS's thread pool is
# TSan-instrumented, so their synchronisation is invisible to TSan and would
# show as races (CMake refuses SOOC_TSAN with OpenMP). tests/tsan.supp holds
# suppressions for third-party libraries only (libOpenNI2). Only the targets
# of these tests are built (RelWithDebInfo: TSan at -O0 is several times slower).
# test_node_model is left out (the model's arithmetic, ~2 min under TSan; its
# `sooc3d node` threads are test_node_signal's) and test_node_slots runs 4 of
# the slot counts (SOOC_TEST_SLOTS; all of them in the passes above).
TSAN_TESTS="test_node_units test_node_e2e test_node_race test_node_signal sooc3d_node_fake test_node_slots sooc3d
  sooc3d-planner-example test_table_basic test_table_stress test_table_crash test_table_examples"
cmake -S . -B build-ci-tsan -DSOOC_WERROR=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSOOC_TSAN=ON -DSOOC_OPENMP=OFF \
  -DSOOC_BUILD_BENCH=OFF >/dev/null
# shellcheck disable=SC2086
cmake --build build-ci-tsan -j"$JOBS" --target $TSAN_TESTS
(cd build-ci-tsan && OPENBLAS_NUM_THREADS=1 SOOC_TEST_SLOTS=0,10,17,32 \
  TSAN_OPTIONS="halt_on_error=1 atexit_sleep_ms=0 second_deadlock_stack=1 suppressions=$PWD/../tests/tsan.supp" \
  ctest --output-on-failure -j"$JOBS" -R "^test_(node_(units|floor_real|e2e|race|signal|slots)|table_(basic|stress|crash|examples))$")
echo "all tests passed"
