#!/usr/bin/env bash
# Runs one libFuzzer harness for a bounded time from the seed corpus; fails (and keeps the
# crashing input in WORK_DIR) on any crash, sanitizer report, leak or timeout.
# usage: run_fuzzer.sh FUZZER SECONDS SEED_DIR WORK_DIR
set -euo pipefail
fuzzer=$1 seconds=$2 seeds=$3 work=$4
rm -rf "$work" && mkdir -p "$work/corpus"
cd "$work"
"$fuzzer" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=8192 -print_final_stats=1 \
  -artifact_prefix="$work/" corpus "$seeds" 2>fuzz.log || { tail -40 fuzz.log; echo "FAIL: $fuzzer (input kept in $work)"; exit 1; }
grep -E "stat::number_of_executed_runs|stat::new_units_added" fuzz.log || true
echo "ok: $(basename "$fuzzer") ran ${seconds} s without a finding"
