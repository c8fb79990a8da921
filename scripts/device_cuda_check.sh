#!/usr/bin/env bash
# One batch of GPU checks for a machine with an NVIDIA GPU but no Debian packages: the CUDA
# parity suite, `hpcm bench --backend cuda` at the paper's size, on the abdomen CT and on larger
# lattices, the main job on the GPU, and a compute-sanitizer pass. It runs prebuilt x86-64
# binaries (built on Debian 12 with nvcc, CMAKE_CUDA_ARCHITECTURES 90) from a folder that holds
#   BIN/bin/{hpcm,hpcm_test_cuda_parity}, BIN/lib/<their shared libraries>, BIN/data/abdomen_ct.nii.gz
# Usage: scripts/device_cuda_check.sh BIN RESULTS_DIR   (HPCM_DEVICE_LARGE=0 leaves out the 78.6 M lattice)
# Every step has its own time limit; results go to RESULTS_DIR as they come (log + a tarball).
set -uo pipefail
BIN=$(cd "$1" && pwd)
RES=$2
mkdir -p "$RES"
WORK=$(mktemp -d)
export LD_LIBRARY_PATH="$BIN/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export HPCM_NO_PROGRESS=1
HPCM="$BIN/bin/hpcm"
LOG="$RES/device.log"
save() { tar czf "$RES/results.tgz" -C "$WORK" . 2>/dev/null; }
step() {  # step NAME SECONDS CMD...
  local name=$1 secs=$2
  shift 2
  echo "=== $name (limit ${secs}s, $(date +%T))" | tee -a "$LOG"
  local t0=$SECONDS
  timeout "$secs" "$@" >"$WORK/$name.out" 2>&1
  local rc=$?
  tail -n 40 "$WORK/$name.out" | tee -a "$LOG"
  echo "--- $name: exit $rc after $((SECONDS - t0)) s" | tee -a "$LOG"
  save
}

step info 20 bash -c 'nvidia-smi; nvcc --version | tail -1; uname -a; nproc; grep -m1 "model name" /proc/cpuinfo; ldd '"$HPCM"' | grep "not found" || echo "all libraries found"'
step parity 150 "$BIN/bin/hpcm_test_cuda_parity" --gtest_color=no
cd "$WORK"
step bench_phantom128 60 "$HPCM" bench --backend cuda --phantom 128,128,75 --frames 150 --out bench_phantom128
step bench_abdomen 60 "$HPCM" bench --backend cuda --input "$BIN/data/abdomen_ct.nii.gz" --frames 150 --out bench_abdomen
step bench_phantom128_cpu16 60 "$HPCM" bench --backend cpu --phantom 128,128,75 --dynamics viscoelastic --frames 150 --out bench_phantom128_cpu16
step bench_awake_C 60 "$HPCM" bench --backend cuda --phantom 128,128,75 --dynamics viscoelastic --frames 150 --awake-reference --out bench_awake_C
step experiment96 100 "$HPCM" experiment --backend cuda --phantom 96,96,64 --no-report --out experiment96
step bench_phantom256 60 "$HPCM" bench --backend cuda --phantom 256,256,150 --dynamics viscoelastic --frames 60 --warmup 2 --out bench_phantom256
step memcheck 60 compute-sanitizer --tool memcheck --error-exitcode 9 "$BIN/bin/hpcm_test_cuda_parity" --gtest_color=no --gtest_filter=CudaParity.WavesOnThePhantom:CudaParity.LinkRestoration
# A build with -lineinfo, when carried, names source lines in the race reports.
PARITY_LINES="$BIN/bin/hpcm_test_cuda_parity_lineinfo"
[ -x "$PARITY_LINES" ] || PARITY_LINES="$BIN/bin/hpcm_test_cuda_parity"
step racecheck 60 compute-sanitizer --tool racecheck --error-exitcode 9 "$PARITY_LINES" --gtest_color=no --gtest_filter=CudaParity.WavesOnThePhantom
[ "${HPCM_DEVICE_LARGE:-1}" != 0 ] && step bench_phantom512 100 "$HPCM" bench --backend cuda --phantom 512,512,300 --dynamics viscoelastic --frames 30 --warmup 1 --out bench_phantom512
echo "=== summary" | tee -a "$LOG"
grep -h -- "^--- " "$LOG"
grep -h "\[parity\]\|PASSED\|FAILED\|SKIPPED" "$WORK/parity.out" | tail -30
for d in bench_phantom128 bench_abdomen bench_phantom128_cpu16 bench_awake_C bench_phantom256 bench_phantom512; do
  [ -f "$WORK/$d.out" ] && grep -h "hpcm bench\|^[ABC] (\|Velocity layer bandwidth\|Device memory\|all-awake" "$WORK/$d.out"
done
grep -h "checks\|hold" "$WORK/experiment96.out" | tail -8
