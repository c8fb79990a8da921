#!/bin/sh
# A pull the tissue cannot follow (12 cells anterior from the skin of a 48x48x32 phantom:
# beyond the lattice border): the viewer says once, on its output, that the pull was
# limited, with the achieved and the requested offset; the tool is drawn where the tissue is
# and the requested position is marked. A pull of 3 cells (feasible) says nothing and marks
# nothing.
# usage: viewer_limited_pull.sh VIEWER PNGCHECK OUTDIR
# Exits 77 (skipped) when xvfb-run is not installed.
set -u
VIEWER=$1
CHECK=$2
OUT=$3
. "$(dirname "$0")/common.sh"
scenario() {  # NAME PULL: grab the paper point, pull anterior by PULL over 6 frames, hold
  cat >"$OUT/$1.toml" <<EOS
[scenario]
name = "$1"
frames = 14
[[grab]]
centre = "auto"
start = 0
release = 14
keyframes = [ [6, 0.0, -$2, 0.0] ]
EOS
}
run() {
  echo "+ hpcm-viewer --phantom 48,48,32 --scenario $1.toml --frames 10"
  xrun --phantom 48,48,32 --scenario "$OUT/$1.toml" --frames 10 \
    --hide-panel --screenshot "$OUT/$1.png" --report "$OUT/$1.txt" >"$OUT/$1.log" 2>&1 ||
    { cat "$OUT/$1.log"; fail "hpcm-viewer exited with $? ($1)"; }
  cat "$OUT/$1.log"
}
field() { awk -v k="$1" -v p="$2" '$1 == k && $2 == p { print $3, $4; exit }' "$3"; }

scenario far 12.0
scenario near 3.0
run far
run near

# Said once, with both offsets.
[ "$(grep -c 'pull limited' "$OUT/far.log")" -eq 1 ] || fail "expected one 'pull limited' line"
grep -q "pull limited: the tool moved [0-9.]* of the requested 12.00 lattice units" "$OUT/far.log" ||
  fail "the message does not name the achieved and the requested offset"
grep -q "requested (0.00, -12.00, 0.00)" "$OUT/far.log" || fail "the message does not give the requested offset"
grep -q "lattice units ([0-9.]* mm) short" "$OUT/far.log" || fail "the message does not say by how much in mm"
grep -q "pull limited" "$OUT/near.log" && fail "a feasible pull was reported as limited"

# The report: limited, achieved short of the request but moved.
grep -qx "tool_limited 1" "$OUT/far.txt" || fail "report: tool not limited"
grep -qx "tool_limited 0" "$OUT/near.txt" || fail "report: the feasible pull is limited"
AY=$(awk '$1 == "tool_offset" { print $3 }' "$OUT/far.txt")
awk -v y="$AY" 'BEGIN { exit !(y < -1 && y > -12) }' || fail "achieved offset $AY not in (-12, -1)"

# The drawing (sagittal view, where the pull lies in the view plane): the cyan tool ring at
# the achieved position, the orange cross at the requested one (not drawn without a limit).
set -- $(field tool_px sagittal "$OUT/far.txt")
TX=$1 TY=$2
set -- $(field tool_requested_px sagittal "$OUT/far.txt")
RX=$1 RY=$2
[ -n "$TX" ] && [ -n "$RX" ] || fail "report incomplete: $(cat "$OUT/far.txt")"
awk -v a="$TX" -v b="$RX" 'BEGIN { d = a - b; exit !(d > 20 || d < -20) }' || fail "requested and achieved drawn at the same place"
CYAN=$("$CHECK" count "$OUT/far.png" "$TX" "$TY" 20 0 240 255 40) || fail count
ORANGE=$("$CHECK" count "$OUT/far.png" "$RX" "$RY" 8 255 150 40 60) || fail count
ORANGE_NEAR=$("$CHECK" count "$OUT/near.png" "$RX" "$RY" 8 255 150 40 60) || fail count
echo "cyan pixels at the tool: $CYAN; orange pixels at the requested position: $ORANGE (feasible pull: $ORANGE_NEAR)"
[ "$CYAN" -ge 20 ] || fail "no tool ring at the achieved position ($TX, $TY)"
[ "$ORANGE" -ge 10 ] || fail "no marker at the requested position ($RX, $RY)"
[ "$ORANGE_NEAR" -le 2 ] || fail "a marker is drawn without a limited pull"
echo "PASS"
