#!/usr/bin/env bash
# Runs one libFuzzer harness of tests/fuzz (or all of them, one after the other) for a number of seconds.
#   scripts/fuzz.sh TARGET SECONDS     TARGET: ply obj off stl job journal gim_archive sphere_archive mcgim_archive
#                                      relief_archive batch_shard batch_archive roi_payload coded_payload, or "all"
# Configures build-fuzz with clang (-DGIMFORGE_FUZZ=ON, ASan+UBSan, only what the harnesses link) when it
# is not configured yet, builds fuzz_TARGET, and runs it on the seeds of tests/fuzz/corpus/TARGET plus a
# working corpus build-fuzz/corpus/TARGET (kept between runs, not committed). One worker (-fork=1), which
# goes on after a crash, a leak-free out-of-memory or a timeout; every such input is saved under
# tests/fuzz/crashes/TARGET/ (crash-*, oom-*, timeout-*). At the end it prints the totals from libFuzzer's
# last status line (execs, exec/s, cov:, ft:, corpus) and appends them to build-fuzz/fuzz-results.tsv.
# Environment: JOBS (build parallelism, default 2), RSS_LIMIT_MB (default 2048), MALLOC_LIMIT_MB (default
# 1024: one allocation larger than this is a finding), TIMEOUT_S (one input slower than this is a finding, default 5 s: the HDF5 hangs found so far would otherwise eat the run),
# FUZZ_NO_BUILD=1 (run the executable as built, e.g. while another build of build-fuzz is running).
set -euo pipefail
cd "$(dirname "$0")/.."
TARGETS=(ply obj off stl job journal gim_archive sphere_archive relief_archive mcgim_archive batch_shard batch_archive roi_payload coded_payload)
if [ $# -ne 2 ] || ! [[ "$2" =~ ^[0-9]+$ ]]; then
  echo "usage: scripts/fuzz.sh TARGET|all SECONDS   (targets: ${TARGETS[*]})" >&2
  exit 2
fi
if [ "$1" = all ]; then
  for t in "${TARGETS[@]}"; do "$0" "$t" "$2"; done
  exit 0
fi
TARGET=$1 SECONDS_TOTAL=$2
if ! printf '%s\n' "${TARGETS[@]}" | grep -qx "$TARGET"; then
  echo "fuzz: unknown target '$TARGET' (targets: ${TARGETS[*]})" >&2
  exit 2
fi

BUILD=build-fuzz
if [ ! -f "$BUILD/CMakeCache.txt" ]; then
  GEN=()
  command -v ninja >/dev/null && GEN=(-G Ninja)
  LAUNCHER=()
  if command -v ccache >/dev/null; then
    LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
    export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
  fi
  # Warnings are not errors here: clang's set differs from gcc's, which the normal build enforces.
  CC=clang CXX=clang++ cmake -S . -B "$BUILD" "${GEN[@]}" "${LAUNCHER[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DGIMFORGE_FUZZ=ON -DGIMFORGE_BUILD_TESTS=OFF -DGIMFORGE_BUILD_BENCH=OFF -DGIMFORGE_BUILD_TOOLS=OFF \
    -DGIMFORGE_WERROR=OFF "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1"
fi
[ "${FUZZ_NO_BUILD:-0}" = 1 ] || cmake --build "$BUILD" -j "${JOBS:-2}" --target "fuzz_$TARGET"

SEEDS=tests/fuzz/corpus/$TARGET
WORK=$BUILD/corpus/$TARGET
CRASHES=tests/fuzz/crashes/$TARGET
LOG=$BUILD/fuzz-$TARGET.log
mkdir -p "$WORK" "$CRASHES"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0:abort_on_error=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export HDF5_USE_FILE_LOCKING=FALSE
echo "fuzz: $TARGET for ${SECONDS_TOTAL} s (log $LOG)"
start=$(date +%s)
set +e
"$BUILD/tests/fuzz/fuzz_$TARGET" -fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
  -max_total_time="$SECONDS_TOTAL" -rss_limit_mb="${RSS_LIMIT_MB:-2048}" -malloc_limit_mb="${MALLOC_LIMIT_MB:-1024}" \
  -timeout="${TIMEOUT_S:-5}" -max_len=65536 -print_funcs=0 -artifact_prefix="$CRASHES/" -print_final_stats=1 \
  "$WORK" "$SEEDS" >"$LOG" 2>&1
rc=$?
set -e
elapsed=$(($(date +%s) - start))
# Fork mode's status lines: "#EXECS: cov: C ft: F corp: N exec/s E oom/timeout/crash: a/b/c time: Ts ..."
last=$(grep -E '^#[0-9]+: cov: ' "$LOG" | tail -1 || true)
execs=$(sed -nE 's/^#([0-9]+):.*/\1/p' <<<"$last")
cov=$(sed -nE 's/.* cov: ([0-9]+).*/\1/p' <<<"$last")
ft=$(sed -nE 's/.* ft: ([0-9]+).*/\1/p' <<<"$last")
corp=$(sed -nE 's/.* corp: ([0-9]+).*/\1/p' <<<"$last")
eps=$([ -n "$execs" ] && [ "$elapsed" -gt 0 ] && echo $((execs / elapsed)) || true)   # average over the run
otc=$(sed -nE 's/.* oom\/timeout\/crash: ([0-9]+\/[0-9]+\/[0-9]+).*/\1/p' <<<"$last")
saved=$(find "$CRASHES" -type f -newermt "@$start" | wc -l)
printf 'fuzz: %s: %s s, %s execs, %s exec/s, cov: %s ft: %s, corpus %s, oom/timeout/crash %s, %s new files in %s (libFuzzer exit %s)\n' \
  "$TARGET" "$elapsed" "${execs:-?}" "${eps:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}" "${otc:-?}" "$saved" "$CRASHES" "$rc"
printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$(date -u +%FT%TZ)" "$TARGET" "$elapsed" "${execs:-}" "${eps:-}" \
  "${cov:-}" "${ft:-}" "${corp:-}" "${otc:-}" "$saved" >>"$BUILD/fuzz-results.tsv"
