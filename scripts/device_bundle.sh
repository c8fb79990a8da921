#!/usr/bin/env bash
# Gathers what scripts/device_cuda_check.sh needs on a GPU machine without Debian packages:
#   OUT/bin/{hpcm,hpcm_test_cuda_parity,hpcm_test_position_independence}, OUT/lib/<their shared
#   libraries but the C library>, OUT/data/abdomen_ct.nii.gz
# Usage: scripts/device_bundle.sh BUILD_DIR OUT_DIR [DATA_DIR]   (DATA_DIR: ../shared/data)
set -euo pipefail
build=$1
out=$2
data=${3:-"$(cd "$(dirname "$0")/.." && pwd)/../shared/data"}
bins=("$build/apps/hpcm/hpcm" "$build/tests/cuda/hpcm_test_cuda_parity"
      "$build/tests/pipeline/hpcm_test_position_independence")
for b in "${bins[@]}"; do
  [ -x "$b" ] || { echo "device_bundle: $b is missing (build with a CUDA compiler first)" >&2; exit 2; }
done
rm -rf "$out"
mkdir -p "$out/bin" "$out/lib" "$out/data"
cp "${bins[@]}" "$out/bin/"
# Every library ldd resolves, except the C runtime the target machine has itself.
ldd "${bins[@]}" | awk '/=> \//{print $3}' | sort -u \
  | grep -v -E '/(libc|libm|libpthread|libdl|librt|ld-linux[^/]*)\.so' \
  | while read -r lib; do cp -L "$lib" "$out/lib/"; done
cp "$data/abdomen-ct/abdomen_ct.nii.gz" "$out/data/"
du -sh "$out"
