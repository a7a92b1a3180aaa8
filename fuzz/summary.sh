#!/usr/bin/env bash
# Totals per harness from BUILD_DIR/fuzz-log.tsv (fuzz/run.sh appends one line per run):
#   fuzz/summary.sh [BUILD_DIR]   ->  harness | runs | seconds | executions | failed runs
build=${1:-build-fuzz}
awk -F'\t' '{ runs[$2]++; secs[$2] += $3; if ($4 ~ /^[0-9]+$/) ex[$2] += $4; if ($5 != "ok") bad[$2]++ }
  END { for (t in runs) printf "%s\t%d\t%d\t%d\t%d\n", t, runs[t], secs[t], ex[t], bad[t] }' \
  "$build/fuzz-log.tsv" | sort
