#!/usr/bin/env bash
# One batch on a GPU machine that checks a change against the build before it: the parity
# suite and the position-independence test on the device, compute-sanitizer memcheck and
# racecheck (racecheck over a whole short `hpcm bench`, every kernel of the frame), the
# experiment on the GPU, and `hpcm bench` timed alternately against the old build.
# BIN as scripts/device_bundle.sh writes it, plus BIN/bin-old/hpcm (the build before).
# Usage: scripts/device_verify.sh BIN RESULTS_DIR [PAIRS]
set -uo pipefail
BIN=$(cd "$1" && pwd)
RES=$2
PAIRS=${3:-3}
mkdir -p "$RES"
export LD_LIBRARY_PATH="$BIN/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" HPCM_NO_PROGRESS=1
NEW=$BIN/bin/hpcm OLD=$BIN/bin-old/hpcm
ALT=$(dirname "$0")/device_alternate.sh
W=$(mktemp -d)
step() {  # step NAME SECONDS CMD...
  local name=$1 secs=$2
  shift 2
  echo "=== $name ($(date +%T))"
  timeout "$secs" "$@" >"$W/$name.out" 2>&1
  local rc=$?
  grep -h "\[parity\]\|PASSED\|FAILED\|SKIPPED\|SUMMARY\|^[ABC] (\|experiment:\|failed:\|Device memory\|bandwidth\|\[old\|\[new" "$W/$name.out" | head -40
  echo "--- $name: exit $rc"
  tar czf "$RES/results.tgz" -C "$W" . 2>/dev/null
}
step info 20 bash -c 'nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv; nproc'
step parity 200 "$BIN/bin/hpcm_test_cuda_parity" --gtest_color=no
step position 120 "$BIN/bin/hpcm_test_position_independence" --gtest_color=no
step memcheck 90 compute-sanitizer --tool memcheck --error-exitcode 9 "$NEW" bench --backend cuda --phantom 32,32,24 --dynamics viscoelastic --frames 20 --out "$W/mc"
step racecheck 120 compute-sanitizer --tool racecheck --error-exitcode 9 "$NEW" bench --backend cuda --phantom 32,32,24 --dynamics viscoelastic --frames 20 --out "$W/rc"
step alt_phantom128 200 bash "$ALT" "$OLD" "$NEW" "$PAIRS" "$W/alt128" --backend cuda --phantom 128,128,75 --frames 150
step alt_abdomen 200 bash "$ALT" "$OLD" "$NEW" "$PAIRS" "$W/altabd" --backend cuda --input "$BIN/data/abdomen_ct.nii.gz" --frames 150
step experiment96 120 "$NEW" experiment --backend cuda --phantom 96,96,64 --no-report --out "$W/experiment96"
step bench512 150 "$NEW" bench --backend cuda --phantom 512,512,300 --dynamics viscoelastic --frames 30 --warmup 1 --out "$W/bench512"
for d in alt128/new_1 altabd/new_1 bench512; do [ -f "$W/$d/bench.json" ] && cp "$W/$d/bench.json" "$RES/$(echo "$d" | tr / _).json"; done
echo "=== done"
