#!/usr/bin/env bash
# Times two builds of hpcm against each other on one machine, alternating old and new so that
# both see the same load: `hpcm bench ARGS...` PAIRS times each, printing each run's per-condition
# line (stage medians, worst frame in parentheses). Used on the GPU machine, where the builds come
# from scripts/device_bundle.sh (OLD_BIN/bin/hpcm and NEW_BIN/bin/hpcm share NEW_BIN/lib).
# Usage: scripts/device_alternate.sh OLD_HPCM NEW_HPCM PAIRS OUT_DIR bench-arguments...
set -uo pipefail
old=$1 new=$2 pairs=$3 out=$4
shift 4
mkdir -p "$out"
for ((i = 1; i <= pairs; i++)); do
  for which in old new; do
    exe=$old
    [ "$which" = new ] && exe=$new
    dir="$out/${which}_$i"
    timeout 120 "$exe" bench "$@" --out "$dir" >"$dir.log" 2>&1
    echo "[$which $i, exit $?] $(grep -h '^[ABC] (' "$dir.log" | tr -s ' ' | paste -sd ';')"
  done
done
