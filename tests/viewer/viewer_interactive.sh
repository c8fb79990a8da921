#!/bin/sh
# Interactive use of hpcm-viewer driven by xdotool under Xvfb: left-drag on the axial view
# grabs the skin and pulls it, n steps single frames, s writes a screenshot, releasing the
# button releases the tissue, Escape quits with exit code 0.
# usage: viewer_interactive.sh VIEWER PNGCHECK OUTDIR
# Exits 77 (skipped) when xvfb-run or xdotool is not installed.
set -u
VIEWER=$1
CHECK=$2
OUT=$3
PHANTOM=32,32,24
for tool in xvfb-run xdotool; do
  if ! command -v $tool >/dev/null 2>&1; then
    echo "SKIP: $tool not found (Debian packages xvfb, xdotool)"
    exit 77
  fi
done
export LIBGL_ALWAYS_SOFTWARE=1
mkdir -p "$OUT"
rm -f "$OUT"/*.png "$OUT"/*.txt "$OUT"/*.log
cd "$OUT" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
# Rest screenshot and the pixel of the paper grab point (scripted mode).
xvfb-run -a -s "-screen 0 1280x800x24" "$VIEWER" --phantom $PHANTOM --scenario none --frames 0 \
  --screenshot rest.png --report rest.txt >/dev/null || fail "scripted start"
set -- $(awk '$1 == "grab_px" && $2 == "axial" { printf "%d %d", $3, $4; exit }' rest.txt)
GX=$1 GY=$2
CELL=$(awk '$1 == "view" && $2 == "axial" { print $10; exit }' rest.txt)

cat >drive.sh <<EOS
#!/bin/sh
set -u
"$VIEWER" --phantom $PHANTOM --paused >viewer.log 2>&1 &
VPID=\$!
WID=\$(xdotool search --sync --onlyvisible --name "hpcm-viewer" | head -n 1)
sleep 2
wait_png() { n=0; while [ \$(ls hpcm-viewer-*.png 2>/dev/null | wc -l) -lt \$1 ] && [ \$n -lt 600 ]; do sleep 0.1; n=\$((n+1)); done; }
xdotool mousemove $GX $GY
sleep 0.5
xdotool mousedown 1
sleep 0.5
for k in 1 2 3 4 5 6; do
  xdotool mousemove $GX \$(( $GY - k * $(printf '%.0f' "$CELL") ))
  sleep 0.3
  xdotool key n
  sleep 0.5
done
xdotool key s
wait_png 1
xdotool mouseup 1
sleep 0.5
for k in 1 2 3 4; do xdotool key n; sleep 0.3; done
xdotool key s
wait_png 2
xdotool key Escape
wait \$VPID
echo "viewer exit \$?" >exit.txt
EOS
chmod +x drive.sh
timeout 300 xvfb-run -a -s "-screen 0 1280x800x24" ./drive.sh || fail "driver failed or timed out"
cat viewer.log
grep -qx "viewer exit 0" exit.txt || fail "$(cat exit.txt 2>/dev/null)"
set -- $(ls hpcm-viewer-*.png)
[ $# -eq 2 ] || fail "expected two screenshots, got: $*"
HELD=$1 RELEASED=$2
"$CHECK" size "$HELD" 1280 800 || fail "screenshot size"
R=$(awk -v c="$CELL" 'BEGIN { print 3 * c }')
D=$("$CHECK" diff rest.png "$HELD" "$GX" "$GY" "$R") || fail diff
D2=$("$CHECK" diff rest.png "$RELEASED" "$GX" "$GY" "$R") || fail diff
echo "grabbed region vs rest: while held $D, after release $D2"
awk -v d="$D" 'BEGIN { exit !(d >= 2.0) }' || fail "the drag did not deform the grabbed region ($D)"
echo "PASS"
