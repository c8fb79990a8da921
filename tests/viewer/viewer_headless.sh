#!/bin/sh
# Headless test of hpcm-viewer under Xvfb + Mesa (issue 6, item 5):
#   the viewer starts, plays the paper-protocol scenario, writes a screenshot of the requested
#   size, the grabbed region differs measurably from the same scene with no input (and from
#   the first frame of the protocol) while two runs of the same scene are identical there, the
#   grab tool is drawn where the report says it is, and the program exits 0.
# usage: viewer_headless.sh VIEWER PNGCHECK OUTDIR [NX,NY,NZ] [FRAMES] [SCENARIO]
#   SCENARIO: the paper-protocol TOML file, or the word paper (default)
# Exits 77 (skipped) when xvfb-run is not installed.
set -u
VIEWER=$1
CHECK=$2
OUT=$3
PHANTOM=${4:-64,64,40}
FRAMES=${5:-40}
SCENARIO=${6:-paper}
W=1280
H=800

if ! command -v xvfb-run >/dev/null 2>&1; then
  echo "SKIP: xvfb-run not found (install the Debian package xvfb)"
  exit 77
fi
export LIBGL_ALWAYS_SOFTWARE=1
mkdir -p "$OUT"
rm -f "$OUT"/*.png "$OUT"/*.txt

fail() { echo "FAIL: $*"; exit 1; }
run() {
  name=$1
  shift
  echo "+ hpcm-viewer $*"
  xvfb-run -a -s "-screen 0 ${W}x${H}x24" "$VIEWER" --size ${W}x${H} --phantom "$PHANTOM" \
    --screenshot "$OUT/$name.png" --report "$OUT/$name.txt" "$@" || fail "hpcm-viewer exited with $? ($name)"
  [ -s "$OUT/$name.png" ] || fail "no screenshot $OUT/$name.png"
  "$CHECK" size "$OUT/$name.png" $W $H || fail "$name.png is not ${W}x${H}"
}
field() { awk -v k="$1" -v p="$2" '$1 == k && $2 == p { print $3, $4; exit }' "$3"; }
ge() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a >= b) }'; }

run paper --scenario "$SCENARIO" --frames "$FRAMES"
run none --scenario none --frames "$FRAMES"
run none2 --scenario none --frames "$FRAMES"
run first --scenario "$SCENARIO" --frames 1

set -- $(field grab_px axial "$OUT/paper.txt")
GX=$1 GY=$2
CELL=$(awk '$1 == "view" && $2 == "axial" { print $10; exit }' "$OUT/paper.txt")
set -- $(field tool_px axial "$OUT/paper.txt")
TX=$1 TY=$2
TR=$(field tool_radius_px axial "$OUT/paper.txt" | awk '{ print $1 }')
[ -n "$GX" ] && [ -n "$CELL" ] && [ -n "$TX" ] && [ -n "$TR" ] || fail "report incomplete: $(cat "$OUT/paper.txt")"
echo "grab point at ($GX, $GY), tool at ($TX, $TY) radius $TR px, $CELL px per cell"

# Region: 3 cells around the grab point's rest position (the tool, pulled 6 cells anterior,
# is drawn outside it). Control: two runs of the same scene give the same pixels there.
R=$(awk -v c="$CELL" 'BEGIN { print 3 * c }')
D_NONE=$("$CHECK" diff "$OUT/paper.png" "$OUT/none.png" "$GX" "$GY" "$R") || fail "diff"
D_FIRST=$("$CHECK" diff "$OUT/paper.png" "$OUT/first.png" "$GX" "$GY" "$R") || fail "diff"
D_SAME=$("$CHECK" diff "$OUT/none.png" "$OUT/none2.png" "$GX" "$GY" "$R") || fail "diff"
echo "mean |difference| (0..255) in the grabbed region: vs no input $D_NONE, vs frame 1 $D_FIRST, same scene twice $D_SAME"
ge "$D_NONE" 2.0 || fail "grabbed region does not differ from the scene with no input ($D_NONE < 2)"
ge "$D_FIRST" 2.0 || fail "grabbed region does not differ from frame 1 ($D_FIRST < 2)"
ge 0.01 "$D_SAME" || fail "two runs of the same scene differ in the grabbed region ($D_SAME)"

# The tool (released, drawn as a light ring) is where the report puts it, and only there.
RING=$("$CHECK" ring "$OUT/paper.png" "$TX" "$TY" "$TR") || fail "ring"
RING_NONE=$("$CHECK" ring "$OUT/none.png" "$TX" "$TY" "$TR") || fail "ring"
echo "bright pixels on the tool ring: $RING (no input: $RING_NONE)"
ge "$RING" 0.6 || fail "grab tool not drawn at ($TX, $TY)"
ge 0.2 "$RING_NONE" || fail "the scene without input shows a ring at the tool position"
echo "PASS"
