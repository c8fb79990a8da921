#!/usr/bin/env bash
# Without a CUDA device, `hpcm run --backend cuda` and `hpcm bench --backend cuda` must exit
# non-zero and say "no CUDA device". Where a device is present the run succeeds: skip (77).
set -u
HPCM="$1"
OUT="$2"
rm -rf "$OUT"
mkdir -p "$OUT"
out=$("$HPCM" run --backend cuda --phantom 16,16,16 --frames 1 --out "$OUT/run" 2>&1)
rc=$?
if [ $rc -eq 0 ]; then
  echo "a CUDA device is present (hpcm run --backend cuda succeeded): skipping the no-device check"
  exit 77
fi
echo "$out"
if ! grep -q "no CUDA device" <<<"$out"; then
  echo "FAIL: hpcm run --backend cuda exited $rc without saying 'no CUDA device'"
  exit 1
fi
out=$("$HPCM" bench --backend cuda --phantom 16,16,16 --frames 2 --out "$OUT/bench" 2>&1)
rc=$?
echo "$out"
if [ $rc -eq 0 ] || ! grep -q "no CUDA device" <<<"$out"; then
  echo "FAIL: hpcm bench --backend cuda exited $rc; expected non-zero and 'no CUDA device'"
  exit 1
fi
echo "ok: both commands exit non-zero with 'no CUDA device'"
