#!/usr/bin/env bash
# Runs the libFuzzer targets of a fuzz build, each for SECONDS from its seed corpus
# (tests/fuzz/corpus/<target>/), one after the other:
#   tests/fuzz/run-fuzzers.sh BUILD_DIR SECONDS [TARGET ...]      (TARGET: model_file, event_log, ...)
# New inputs go to a work corpus (WORK_DIR, default BUILD_DIR/fuzz-corpus/<target>; the seeds in
# the repository are only read). Crashes, leaks, UBSan reports (built with
# -fno-sanitize-recover) and timeouts are written to WORK_DIR/<target>/artifacts/ and fail the
# run. One line per target: seconds, executions, corpus size, result. Exit 0 when none failed.
# FUZZ_JOBS=N runs N targets at a time (default 1; .ci/run uses one per core): each target is
# one process and still gets its SECONDS.
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="${1:?usage: run-fuzzers.sh BUILD_DIR SECONDS [TARGET ...]}"
seconds="${2:?usage: run-fuzzers.sh BUILD_DIR SECONDS [TARGET ...]}"
shift 2
targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
  targets=(dataset bench_config model_file event_log lcm_decode stream_assembler can_frame_map modbus_registers)
fi
work="${WORK_DIR:-$build/fuzz-corpus}"
parallel="${FUZZ_JOBS:-1}"

# run_one TARGET: fuzzes TARGET, writes its line to $work/TARGET/result; exit 1 when it failed.
run_one() {
  local t="$1"
  local bin="$build/fuzz/fuzz_$t"
  mkdir -p "$work/$t/corpus" "$work/$t/artifacts"
  if [ ! -x "$bin" ]; then
    echo "fuzz $t: $bin is not built (cmake --build $build --target fuzz_$t)" > "$work/$t/result"
    return 1
  fi
  local log="$work/$t/fuzz.log" stamp="$work/$t/started" start rc took execs corpus artifacts result
  start=$(date +%s)
  # Only what this run writes counts: a WORK_DIR used before keeps the artifacts of earlier runs
  # (findings since fixed, their inputs kept as seeds), which must not fail this one.
  touch "$stamp"
  # -rss_limit_mb: a reader that allocates what a hostile length claims is a finding, not noise.
  # -timeout: one input taking 10 s is a hang. -print_final_stats: the figures below.
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:${ASAN_OPTIONS:-}" \
  UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}" \
    "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
      -artifact_prefix="$work/$t/artifacts/" "$work/$t/corpus" "$here/corpus/$t" >"$log" 2>&1
  rc=$?
  took=$(( $(date +%s) - start ))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  corpus=$(ls "$work/$t/corpus" | wc -l)
  artifacts=$(find "$work/$t/artifacts" -type f -newer "$stamp" | wc -l)
  if [ "$rc" -eq 0 ] && [ "$artifacts" -eq 0 ]; then
    result=ok
  else
    result="FAILED (exit $rc; artifacts in $work/$t/artifacts; log $log)"
  fi
  {
    [ "$result" = ok ] || grep -E "ERROR|SUMMARY|runtime error" "$log" | head -5
    echo "fuzz $t: ${took} s, ${execs:-0} executions, corpus ${corpus} new inputs, ${artifacts} crashes: $result"
  } > "$work/$t/result"
  [ "$result" = ok ]
}

failed=0
running=0
for t in "${targets[@]}"; do
  if [ "$running" -ge "$parallel" ]; then
    wait -n || failed=1
    running=$((running - 1))
  fi
  run_one "$t" &
  running=$((running + 1))
done
while [ "$running" -gt 0 ]; do
  wait -n || failed=1
  running=$((running - 1))
done
for t in "${targets[@]}"; do cat "$work/$t/result"; done
exit "$failed"
