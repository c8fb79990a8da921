#!/usr/bin/env bash
# Configures and builds the given CMake presets one after the other (scripts/test.sh starts it
# in the background at the lowest CPU priority while the Release tests run). For each preset
# it writes LOGDIR/PRESET.log (the configure and build output) and then LOGDIR/PRESET.status
# (0: built; otherwise the failing step's exit status), which test.sh waits for.
# usage: stage_builds.sh LOGDIR JOBS PRESET...
set -uo pipefail
cd "$(dirname "$0")/.."
logs=$1 jobs=$2
shift 2
for preset in "$@"; do
  status=0
  cmake --preset "$preset" >"$logs/$preset.log" 2>&1 || status=$?
  if [ "$status" = 0 ]; then
    cmake --build --preset "$preset" -j "$jobs" >>"$logs/$preset.log" 2>&1 || status=$?
  fi
  echo "$status" >"$logs/$preset.status.tmp" && mv "$logs/$preset.status.tmp" "$logs/$preset.status"
done
