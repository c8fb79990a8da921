#!/bin/sh
# hpcm-viewer plays a scenario in millimetres (offset_mm, radius_mm; issue 32): the same pull
# in mm on two lattices of the same field of view (the second with twice the spacing), and the
# report gives the achieved pull in millimetres.
# usage: viewer_mm.sh VIEWER OUTDIR
# Exits 77 (skipped) when xvfb-run is not installed.
set -u
VIEWER=$1
OUT=$2
if ! command -v xvfb-run >/dev/null 2>&1; then
  echo "SKIP: xvfb-run not found (install the Debian package xvfb)"
  exit 77
fi
export LIBGL_ALWAYS_SOFTWARE=1
mkdir -p "$OUT"
fail() { echo "FAIL: $*"; exit 1; }
printf '[scenario]\nname = "pull_mm"\nframes = 12\n\n[[grab]]\ncentre = "auto"\nradius_mm = 20.0\nrelease = 12\nkeyframes = [{ frame = 10, offset_mm = [0.0, -30.0, 0.0] }]\n' \
  >"$OUT/pull_mm.toml"
for phantom in 64,64,40 32,32,20; do
  rm -f "$OUT/$phantom.txt"
  xvfb-run -a -s "-screen 0 640x400x24" "$VIEWER" --size 640x400 --phantom "$phantom" --scenario "$OUT/pull_mm.toml" \
    --frames 11 --screenshot "$OUT/$phantom.png" --report "$OUT/$phantom.txt" >"$OUT/$phantom.log" 2>&1 \
    || fail "hpcm-viewer exited with $? on phantom $phantom: $(cat "$OUT/$phantom.log")"
  set -- $(awk '$1 == "tool_offset_mm" { print $2, $3 }' "$OUT/$phantom.txt")
  [ $# -eq 2 ] || fail "no tool_offset_mm in the report: $(cat "$OUT/$phantom.txt")"
  awk -v a="$1" -v r="$2" 'BEGIN { exit !(a > 29.99 && a < 30.01 && r > 29.99 && r < 30.01) }' \
    || fail "phantom $phantom: pull $1 of $2 mm, expected 30 of 30"
  echo "phantom $phantom: the tool moved $1 of the requested $2 mm"
done
echo "PASS"
