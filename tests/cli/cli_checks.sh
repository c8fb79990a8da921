#!/usr/bin/env bash
# hpcm phantom / run checks: four tissue classes, plain HP-ChainMail keeps every link within
# its box (max_link_violation <= 1e-5 in every frame), the pull grows to 6, bad options fail.
set -u
HPCM=$1
OUT=$2
rm -rf "$OUT" && mkdir -p "$OUT"
fail() { echo "FAIL: $*"; exit 1; }

"$HPCM" phantom --size 64,64,48 --summary > "$OUT/summary.txt" || fail "phantom --summary exited non-zero"
for t in air skin_fat muscle_organ bone; do
  n=$(awk -v t="$t" '$1 == t {print $2}' "$OUT/summary.txt")
  [ -n "$n" ] && [ "$n" -gt 0 ] || fail "class $t is empty or missing: $(cat "$OUT/summary.txt")"
done

"$HPCM" run --phantom 64,64,48 --dynamics none --frames 80 --out "$OUT/run" > "$OUT/run.log" 2>&1 \
  || fail "run exited non-zero: $(cat "$OUT/run.log")"
csv="$OUT/run/frames.csv"
[ -f "$csv" ] || fail "no frames.csv"
rows=$(($(wc -l < "$csv") - 1))
[ "$rows" -eq 80 ] || fail "frames.csv has $rows rows, expected 80"
head -1 "$csv" | grep -q '^frame,stage,grab_offset,moved_elements,active_bricks,max_link_violation,chainmail_ms,sim_total_ms' \
  || fail "frames.csv header: $(head -1 "$csv")"
awk -F, 'NR > 1 && ($6 < 0 || $6 > 1e-5) { print "FAIL: frame " $1 " max_link_violation " $6; bad = 1 } END { exit bad }' "$csv" || exit 1
# Deform rows: grab_offset grows (non-decreasing) up to 6.
awk -F, 'NR > 1 && $2 == "deform" { if ($3 + 1e-6 < last) { print "FAIL: grab_offset decreases at frame " $1; bad = 1 } last = $3; mx = ($3 > mx ? $3 : mx) }
         END { if (mx < 6 - 1e-4 || mx > 6 + 1e-4) { print "FAIL: largest grab_offset " mx ", expected 6"; bad = 1 } exit bad }' "$csv" || exit 1

if "$HPCM" run --frames -3 --out "$OUT/bad" > "$OUT/bad.log" 2>&1; then fail "--frames -3 accepted"; fi
grep -q -- "--frames" "$OUT/bad.log" || fail "--frames -3 message does not name the option: $(cat "$OUT/bad.log")"
echo "PASS"
