#!/usr/bin/env bash
# Runs libFuzzer harnesses (docs/robustness.md):
#   fuzz/run.sh BUILD_DIR SECONDS TARGET...
# Each TARGET runs SECONDS on BUILD_DIR/corpus/TARGET (what earlier runs kept) plus the seeds in
# BUILD_DIR/seeds/TARGET; FUZZ_JOBS (default 1) targets run side by side. A crash, leak, timeout
# or out-of-memory input is written to BUILD_DIR/crashes/TARGET/ and the run fails. One line per
# run is appended to BUILD_DIR/fuzz-log.tsv: UTC start, target, seconds it ran, executions, result.
set -u
build=${1:?usage: fuzz/run.sh BUILD_DIR SECONDS TARGET...}
seconds=${2:?seconds}
shift 2
jobs=${FUZZ_JOBS:-1}
status=0

run_one() {
  local t=$1
  local corpus=$build/corpus/$t crashes=$build/crashes/$t log=$build/logs/$t.$(date -u +%Y%m%dT%H%M%S).log
  mkdir -p "$corpus" "$crashes" "$build/logs"
  local start t0
  start=$(date -u +%Y-%m-%dT%H:%M:%SZ)
  t0=$(date +%s)
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0 \
    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$build/$t" "$corpus" "$build/seeds/$t" -max_total_time="$seconds" -timeout=20 \
    -rss_limit_mb=2560 -malloc_limit_mb=1024 -print_final_stats=1 \
    -artifact_prefix="$crashes/" >"$log" 2>&1
  local rc=$?
  local elapsed=$(($(date +%s) - t0))
  local execs
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  local result=ok
  [ $rc -ne 0 ] && result="FAILED(rc=$rc, see $log)"
  printf '%s\t%s\t%s\t%s\t%s\n' "$start" "$t" "$elapsed" "${execs:-?}" "$result" >>"$build/fuzz-log.tsv"
  echo "fuzz: $t: ${elapsed} s, ${execs:-?} executions: $result"
  return $rc
}

pids=()
for t in "$@"; do
  run_one "$t" &
  pids+=($!)
  if [ ${#pids[@]} -ge "$jobs" ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || status=1; done
exit $status
