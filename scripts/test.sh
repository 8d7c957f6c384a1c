#!/usr/bin/env bash
# Run every test: installs missing packages, then builds and tests
# (Release with OpenMP, and ASan/UBSan without OpenMP), with -Werror; then the
# threaded parts (the model's task pool, OpenMP regions, the node's threads)
# once more under ASan/UBSan with OpenMP on, and the node and table tests under
# ThreadSanitizer. The last line counts the skipped tests, those that need the
# real recordings (SOOC_SHARED_REAL, ../shared/real) apart.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
JOBS=$(nproc)
# Skipped tests (exit code 77: no real data, no OpenCV, no hardware, ...) of
# every ctest pass, one line each: pass, test, first output line. The summary
# line at the end counts them, and those that skipped for want of the real
# recordings (SOOC_SHARED_REAL, ../shared/real) apart.
SKIPS=$(mktemp)
trap 'rm -f "$SKIPS"' EXIT
# ct <build dir> <pass name> [VAR=value ...] [ctest arguments ...]
ct() {
  local dir=$1 pass=$2; shift 2
  local envs=()
  while [ $# -gt 0 ] && [[ "$1" == *=* ]] && [[ "$1" != -* ]]; do envs+=("$1"); shift; done
  rm -f "$dir/ctest-junit.xml"
  (cd "$dir" && env "${envs[@]}" ctest --output-on-failure -j"$JOBS" --output-junit ctest-junit.xml "$@")
  python3 - "$dir/ctest-junit.xml" "$pass" >>"$SKIPS" <<'PY'
import sys, xml.etree.ElementTree as ET
path, tag = sys.argv[1], sys.argv[2]
try:
    root = ET.parse(path).getroot()
except (OSError, ET.ParseError):
    sys.exit(0)
for tc in root.iter("testcase"):
    if tc.find("skipped") is None:
        continue
    out = (tc.findtext("system-out") or "").strip().splitlines()
    why = next((l for l in out if "SKIP" in l.upper()), out[0] if out else "")
    print("\t".join((tag, tc.get("name", "?"), why.replace("\t", " "))))
PY
}
run() {
  local dir=$1 filter=$2; shift 2
  cmake -S . -B "$dir" -DSOOC_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j"$JOBS"
  ct "$dir" "$dir" ${filter:+-R "$filter"}
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
  ct build-ci-omp "build-ci-omp $ct" OPENBLAS_CORETYPE="$ct" -R '^test_(nn|model)_'
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
  sooc3d-planner-example test_table_basic test_table_stress test_table_crash test_table_examples
  test_slam_tracker test_slam_node"
cmake -S . -B build-ci-tsan -DSOOC_WERROR=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSOOC_TSAN=ON -DSOOC_OPENMP=OFF \
  -DSOOC_BUILD_BENCH=OFF >/dev/null
# shellcheck disable=SC2086
cmake --build build-ci-tsan -j"$JOBS" --target $TSAN_TESTS
ct build-ci-tsan build-ci-tsan OPENBLAS_NUM_THREADS=1 SOOC_TEST_SLOTS=0,10,17,32 \
  TSAN_OPTIONS="halt_on_error=1 atexit_sleep_ms=0 second_deadlock_stack=1 suppressions=$PWD/tests/tsan.supp" \
  -R "^test_(node_(units|floor_real|e2e|race|signal|slots)|table_(basic|stress|crash|examples)|slam_(tracker|node))$"
# The summary: every skipped run with its reason, then one line counting them,
# the real-data ones apart (their messages name the real data folder).
if [ -s "$SKIPS" ]; then
  echo "== skipped tests (pass, test, reason):"
  sed 's/^/  /' "$SKIPS"
fi
python3 - "$SKIPS" <<'PY'
import re, sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if l.strip()]
real = re.compile(r"real data|SOOC_SHARED_REAL|shared/real", re.I)
r = [x for x in rows if len(x) > 2 and real.search(x[2])]
names = sorted({x[1] for x in r})
other = sorted({x[1] for x in rows if x not in r})
nr, no = len(r), len(rows) - len(r)
print("all tests passed; skipped: %d real-data test run%s (%d test%s%s; they need the recordings in "
      "SOOC_SHARED_REAL or ../shared/real), %d other skipped run%s%s"
      % (nr, "" if nr == 1 else "s", len(names), "" if len(names) == 1 else "s",
         ": " + ", ".join(names) if names else "", no, "" if no == 1 else "s",
         " (" + ", ".join(other) + ")" if other else ""))
PY
