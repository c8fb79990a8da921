#!/bin/sh
# The display does not wait for the simulation (the simulation runs on its own thread):
#   1. a scripted run holds simulation frame 5 (--stall-frame 5) until the display has drawn
#      30 more frames: the run finishes, says so, and reports the display and simulation
#      frame counts; a display that waited for the frame would never release it (the viewer
#      then exits non-zero after its deadline);
#   2. --record (lock-step) writes every frame once, also across a held frame;
#   3. --bench-drag reports display and simulation frame counts (no speed is asserted here:
#      the numbers depend on the machine; see docs/viewer.md for measured ones).
# usage: viewer_decoupled.sh VIEWER OUTDIR
# Exits 77 (skipped) when xvfb-run is not installed.
set -u
VIEWER=$1
OUT=$2
. "$(dirname "$0")/common.sh"

echo "+ hpcm-viewer --phantom 48,48,32 --scenario paper --frames 12 --stall-frame 5 --screenshot held.png"
xrun --phantom 48,48,32 --scenario paper --frames 12 --stall-frame 5 --screenshot "$OUT/held.png" \
  --report "$OUT/held.txt" >"$OUT/held.log" 2>&1 || { cat "$OUT/held.log"; fail "hpcm-viewer exited with $?"; }
cat "$OUT/held.log"
HELD=$(sed -n 's/.*simulation frame 5 was held until the display had drawn \([0-9]*\) more frames.*/\1/p' "$OUT/held.log")
[ -n "$HELD" ] || fail "no report of the held frame"
[ "$HELD" -ge 30 ] || fail "the display drew only $HELD frames while frame 5 was held"
DRAWN=$(sed -n 's/.*played 12 frames .* the display drew \([0-9]*\) frames meanwhile.*/\1/p' "$OUT/held.log")
[ -n "$DRAWN" ] || fail "no display frame count"
[ "$DRAWN" -ge "$HELD" ] || fail "display frames $DRAWN < $HELD"
grep -qx "frames 12" "$OUT/held.txt" || fail "the screenshot does not show frame 12: $(grep frames "$OUT/held.txt")"
grep -qx "display_frames $DRAWN" "$OUT/held.txt" || fail "report and output disagree on the display frames"

echo "+ hpcm-viewer --phantom 32,32,24 --scenario paper --frames 6 --stall-frame 3 --record rec/"
xrun --phantom 32,32,24 --scenario paper --frames 6 --stall-frame 3 --record "$OUT/rec" --size 640x400 \
  --hide-panel >"$OUT/rec.log" 2>&1 || { cat "$OUT/rec.log"; fail "hpcm-viewer --record exited with $?"; }
N=$(ls "$OUT/rec" | wc -l)
[ "$N" -eq 6 ] || fail "expected 6 recorded frames, got $N: $(ls "$OUT/rec")"
for k in 1 2 3 4 5 6; do [ -s "$OUT/rec/frame_0000$k.png" ] || fail "frame_0000$k.png missing"; done
grep -q "simulation frame 3 was held" "$OUT/rec.log" || fail "no report of the held frame in --record"

echo "+ hpcm-viewer --phantom 32,32,24 --bench-drag 2"
xrun --phantom 32,32,24 --bench-drag 2 >"$OUT/bench.log" 2>&1 || { cat "$OUT/bench.log"; fail "--bench-drag exited with $?"; }
cat "$OUT/bench.log"
D=$(sed -n 's/^  display: \([0-9]*\) frames.*/\1/p' "$OUT/bench.log")
S=$(sed -n 's/^  simulation: \([0-9]*\) frames.*/\1/p' "$OUT/bench.log")
[ -n "$D" ] && [ -n "$S" ] || fail "the benchmark did not report both frame counts"
[ "$D" -gt 0 ] && [ "$S" -gt 0 ] || fail "display $D, simulation $S frames"
echo "PASS"
