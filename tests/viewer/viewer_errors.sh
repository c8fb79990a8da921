#!/bin/sh
# Error paths of hpcm-viewer: a start without a display and a missing input file give a
# clear one-line message and a non-zero exit code, never a crash (signal, exit >= 128).
# usage: viewer_errors.sh VIEWER OUTDIR
set -u
VIEWER=$1
OUT=$2
mkdir -p "$OUT"
fail() { echo "FAIL: $*"; exit 1; }

# 1. No display.
env -u DISPLAY -u WAYLAND_DISPLAY "$VIEWER" --phantom 16,16,16 --scenario paper --frames 1 \
  --screenshot "$OUT/x.png" >"$OUT/nodisplay.out" 2>"$OUT/nodisplay.err"
rc=$?
echo "no display: exit $rc: $(cat "$OUT/nodisplay.err")"
[ $rc -ne 0 ] && [ $rc -lt 128 ] || fail "exit code $rc without a display"
grep -qx "hpcm-viewer: no display (set DISPLAY or run under xvfb-run)" "$OUT/nodisplay.err" || fail "message"
[ ! -e "$OUT/x.png" ] || fail "a screenshot was written without a display"

# 2. Missing input file (checked before any window opens, so no display is needed).
env -u DISPLAY "$VIEWER" --input "$OUT/does-not-exist.nii.gz" --frames 1 --screenshot "$OUT/y.png" \
  >"$OUT/missing.out" 2>"$OUT/missing.err"
rc=$?
echo "missing input: exit $rc: $(cat "$OUT/missing.err")"
[ $rc -ne 0 ] && [ $rc -lt 128 ] || fail "exit code $rc for a missing input file"
[ "$(wc -l <"$OUT/missing.err")" -eq 1 ] || fail "expected a one-line message"
grep -q "does-not-exist.nii.gz" "$OUT/missing.err" || fail "message does not name the file"

# 3. Missing scenario file and bad options: clear messages too.
env -u DISPLAY "$VIEWER" --scenario "$OUT/nope.toml" >"$OUT/scn.out" 2>"$OUT/scn.err"
rc=$?
echo "missing scenario: exit $rc: $(cat "$OUT/scn.err")"
[ $rc -ne 0 ] && [ $rc -lt 128 ] && grep -q "nope.toml" "$OUT/scn.err" || fail "missing scenario file"
env -u DISPLAY "$VIEWER" --phantom 96,96 >"$OUT/opt.out" 2>"$OUT/opt.err"
rc=$?
echo "bad --phantom: exit $rc: $(cat "$OUT/opt.err")"
[ $rc -ne 0 ] && [ $rc -lt 128 ] && grep -q -- "--phantom" "$OUT/opt.err" || fail "bad --phantom"

# 3b. HU window options out of range or not finite (nan, inf, a float overflow): refused with the range.
for bad in "--level nan" "--level inf" "--level 1e39" "--level -40000" "--window nan" "--window 0" "--window 1e39"; do
  env -u DISPLAY "$VIEWER" --phantom 16,16,16 $bad >"$OUT/win.out" 2>"$OUT/win.err"
  rc=$?
  echo "$bad: exit $rc: $(cat "$OUT/win.err")"
  [ $rc -ne 0 ] && [ $rc -lt 128 ] || fail "$bad accepted (exit $rc)"
  grep -qE -- "--(level|window): value .*(\[-32768, 32767\]|\(0, 65536\])" "$OUT/win.err" || fail "$bad: message does not give the range"
done

# 4. A display that cannot be opened (DISPLAY names no server).
DISPLAY=:987 "$VIEWER" --phantom 16,16,16 --frames 1 --screenshot "$OUT/z.png" >"$OUT/bad.out" 2>"$OUT/bad.err"
rc=$?
echo "unreachable display: exit $rc: $(cat "$OUT/bad.err")"
[ $rc -ne 0 ] && [ $rc -lt 128 ] && grep -q "display" "$OUT/bad.err" || fail "unreachable display"
echo "PASS"
