#!/usr/bin/env bash
# Run every libFuzzer target (tests/fuzz/README.md) for N executions each and
# print the counts as JSON: one line per target as it finishes, then one object
# with all of them as the last line.
#
#   bash scripts/fuzz.sh [--runs N] [--targets a,b,...] [--build DIR] [--max-time S] [--out DIR] [--resume]
#
# --runs      executions per target (default 10000000)
# --targets   a comma-separated subset (default: every target of tests/fuzz/CMakeLists.txt)
# --build     the clang + ASan build holding fuzz/fuzz_<target> (default build-fuzz; configured and
#             built here when missing, with the flags of tests/fuzz/README.md)
# --max-time  stop a target after S seconds even if N executions are not reached (default: none)
# --out       where new corpus inputs, crashes and logs go (default out/fuzz); the committed corpus
#             in tests/fuzz/corpus is read, never written
# --resume    count executions across runs: OUT/<target>.done holds the executions so far without a
#             finding (each run appends a line to OUT/<target>.runs: date, commit, executions, seconds,
#             status); a run does the executions still missing to N, from the corpus in OUT, and a
#             finding sets the count back to 0. For the slow targets (mapstore_sql: about 500 per s)
#             over several sessions, with --max-time per session.
#
# A target "ok" ran its executions without a crash, leak, timeout or out-of-memory report;
# "interrupted" was ended by SIGINT or SIGTERM to the fuzzer (libFuzzer says "run interrupted"
# and exits 72): the executions it ran count, with --resume too; anything else is "crash" (its
# libFuzzer log and the crashing input are under --out). Exit status: 0 when no target crashed. Needs clang with libFuzzer (Debian: clang, libclang-rt-14-dev).
set -uo pipefail

ROOT="$(cd "$(dirname "$0")/.." && pwd)"
RUNS=10000000
TARGETS=""
BUILD="$ROOT/build-fuzz"
MAXTIME=0
OUT="$ROOT/out/fuzz"
RESUME=0
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) RUNS="$2"; shift 2 ;;
    --targets) TARGETS="${2//,/ }"; shift 2 ;;
    --build) BUILD="$2"; shift 2 ;;
    --max-time) MAXTIME="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --resume) RESUME=1; shift ;;
    -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
    *) echo "fuzz.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
case "$RUNS" in ''|*[!0-9]*) echo "fuzz.sh: --runs wants a positive integer, got '$RUNS'" >&2; exit 2 ;; esac

if [ -z "$TARGETS" ]; then
  TARGETS="$(sed -n '/^set(SOOC_FUZZ_TARGETS/,/)/p' "$ROOT/tests/fuzz/CMakeLists.txt" |
             sed 's/set(SOOC_FUZZ_TARGETS//; s/)//' | tr -s ' \n' ' ')"
fi

if ! command -v clang >/dev/null 2>&1; then
  echo "fuzz.sh: clang is not installed (apt-get install clang libclang-rt-14-dev)" >&2
  exit 77
fi

need_build=0
for t in $TARGETS; do [ -x "$BUILD/fuzz/fuzz_$t" ] || need_build=1; done
if [ "$need_build" = 1 ]; then
  echo "fuzz.sh: building the harnesses in $BUILD" >&2
  if [ ! -f "$BUILD/CMakeCache.txt" ]; then
    CC=clang CXX=clang++ cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSOOC_ASAN=ON \
      -DSOOC_OPENMP=OFF -DSOOC_BUILD_TESTS=OFF -DSOOC_BUILD_BENCH=OFF -DSOOC_WITH_LIBCAMERA=OFF \
      -DSOOC_BUILD_FUZZ=ON >&2 || exit 1
  fi
  for t in $TARGETS; do
    cmake --build "$BUILD" -j"$(nproc)" --target "fuzz_$t" >&2 || { echo "fuzz.sh: fuzz_$t does not build" >&2; exit 1; }
  done
fi

mkdir -p "$OUT"
# the targets that read folders and databases write their input to TMPDIR once per execution: on a
# tmpfs (/dev/shm) when there is one and TMPDIR is not set (mapstore: about 1.5x the executions per s)
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then
  export TMPDIR=/dev/shm
fi
all="" bad=0 total_s=0
commit=$(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)
for t in $TARGETS; do
  bin="$BUILD/fuzz/fuzz_$t"
  work="$OUT/corpus/$t" log="$OUT/$t.log" art="$OUT/crashes/$t/"
  mkdir -p "$work" "$art"
  done_before=0 want="$RUNS"
  if [ "$RESUME" = 1 ]; then
    [ -f "$OUT/$t.done" ] && done_before=$(tr -cd '0-9' < "$OUT/$t.done")
    done_before=${done_before:-0}
    want=$((RUNS - done_before))
    if [ "$want" -le 0 ]; then
      line=$(printf '{"target": "%s", "runs": %s, "asked": %s, "this_run": 0, "seconds": 0, "exec_per_s": 0, "coverage": 0, "status": "ok", "log": "%s"}' \
             "$t" "$done_before" "$RUNS" "$OUT/$t.runs")
      echo "$line"
      all="${all:+$all, }$line"
      continue
    fi
  fi
  args=(-runs="$want" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 -artifact_prefix="$art")
  [ "$MAXTIME" != 0 ] && args+=(-max_total_time="$MAXTIME")
  [ -f "$ROOT/tests/fuzz/dict/$t.dict" ] && args+=(-dict="$ROOT/tests/fuzz/dict/$t.dict")
  asan="${ASAN_OPTIONS:-detect_leaks=1}" lsan="${LSAN_OPTIONS:-}"
  if [ "$t" = ycb_meta ]; then
    # libmatio allocates the array sizes a MAT-file declares before it reads
    # them; when that fails it says so and sooc3d reports the file (corpus/
    # ycb_meta/dims-*.mat). Such an allocation is let fail instead of ending
    # the run; the RSS limit still catches memory that is really used.
    asan="$asan:allocator_may_return_null=1"
    args+=(-malloc_limit_mb=1000000000)
    # libmatio's own leaks on damaged files (tests/fuzz/lsan_libmatio.supp)
    lsan="suppressions=$ROOT/tests/fuzz/lsan_libmatio.supp"
  fi
  t0=$(date +%s.%N)
  ASAN_OPTIONS="$asan" LSAN_OPTIONS="$lsan" "$bin" "${args[@]}" "$work" "$ROOT/tests/fuzz/corpus/$t" >"$log" 2>&1
  rc=$?
  t1=$(date +%s.%N)
  execs=$(sed -n 's/^stat::number_of_executed_units: *\([0-9]*\).*/\1/p' "$log" | tail -1)
  [ -z "$execs" ] && execs=$(sed -n 's/^#\([0-9]*\).*/\1/p' "$log" | tail -1)
  [ -z "$execs" ] && execs=0
  secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')
  rate=$(awk -v n="$execs" -v s="$secs" 'BEGIN { printf "%.0f", (s > 0 ? n / s : 0) }')
  cov=$(sed -n 's/.*cov: \([0-9]*\).*/\1/p' "$log" | tail -1)
  status=ok
  if [ $rc -eq 72 ] && grep -q "libFuzzer: run interrupted" "$log"; then
    status=interrupted
  elif [ $rc -ne 0 ]; then
    status=crash
    bad=$((bad + 1))
  fi
  runs="$execs"
  if [ "$RESUME" = 1 ]; then
    if [ "$status" != crash ]; then runs=$((done_before + execs)); else runs=0; fi
    echo "$runs" > "$OUT/$t.done.tmp" && mv "$OUT/$t.done.tmp" "$OUT/$t.done"
    printf '%s %s %s %s %s\n' "$(date -u +%Y-%m-%dT%H:%M:%SZ)" "$commit" "$execs" "$secs" "$status" >> "$OUT/$t.runs"
  fi
  line=$(printf '{"target": "%s", "runs": %s, "asked": %s, "this_run": %s, "seconds": %s, "exec_per_s": %s, "coverage": %s, "status": "%s", "log": "%s"}' \
         "$t" "$runs" "$RUNS" "$execs" "$secs" "$rate" "${cov:-0}" "$status" "$log")
  echo "$line"
  all="${all:+$all, }$line"
  total_s=$(awk -v a="$total_s" -v b="$secs" 'BEGIN { printf "%.1f", a + b }')
done
printf '{"fuzz": {"runs_per_target": %s, "seconds": %s, "failed": %d, "targets": [%s]}}\n' "$RUNS" "$total_s" "$bad" "$all"
[ $bad -eq 0 ]
