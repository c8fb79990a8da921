#!/usr/bin/env bash
# hpcm phantom / run checks: four tissue classes, plain HP-ChainMail keeps every link within
# its box (max_link_violation <= 1e-5 in every frame), the pull grows to 6, bad options fail;
# a limited pull is reported once (an impossible pull) and not at all (a feasible one).
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

# The pull to 6 is feasible on this phantom: no note that it was limited.
if grep -q "pull was limited" "$OUT/run.log"; then fail "feasible pull reported as limited: $(cat "$OUT/run.log")"; fi

# An impossible pull (40 lattice units on a 48x48x32 phantom): the tool is limited over a
# stretch of frames, and the run says so exactly once, naming that stretch of frames.
printf '[scenario]\nname = "too_far"\nframes = 40\n\n[[grab]]\ncentre = "auto"\nstart = 0\nrelease = 30\nkeyframes = [[20, 0.0, -40.0, 0.0]]\n' \
  > "$OUT/too_far.toml"
"$HPCM" run --phantom 48,48,32 --scenario "$OUT/too_far.toml" --no-link-check --out "$OUT/far" > "$OUT/far.log" 2>&1 \
  || fail "impossible pull: run exited non-zero: $(cat "$OUT/far.log")"
notes=$(grep -c "pull was limited" "$OUT/far.log")
[ "$notes" -eq 1 ] || fail "impossible pull: $notes limited-pull notes, expected exactly 1: $(cat "$OUT/far.log")"
# tool_limited is column 22 of frames.csv; the note names its first and last limited frame.
range=$(awk -F, 'NR > 1 && $22 == 1 { if (first == "") first = $1; last = $1 } END { print first "-" last }' "$OUT/far/frames.csv")
[ "$range" != "-" ] || fail "impossible pull: no frame of frames.csv has tool_limited = 1"
grep -q "pull was limited in frames $range (" "$OUT/far.log" || fail "impossible pull: the note does not name frames $range: $(cat "$OUT/far.log")"
grep -q "of the requested 40 lattice units" "$OUT/far.log" || fail "impossible pull: the note does not give the requested 40: $(cat "$OUT/far.log")"

if "$HPCM" run --frames -3 --out "$OUT/bad" > "$OUT/bad.log" 2>&1; then fail "--frames -3 accepted"; fi
grep -q -- "--frames" "$OUT/bad.log" || fail "--frames -3 message does not name the option: $(cat "$OUT/bad.log")"

# The CPU kernels can be chosen by HPCM_CPU_KERNELS (benchmarks compare the instruction sets);
# the bench names the ones it used, and a value that is not an instruction set is an error.
HPCM_CPU_KERNELS=sse2 "$HPCM" bench --phantom 16,16,12 --frames 3 --out "$OUT/k" > "$OUT/k.log" 2>&1 \
  || fail "bench with HPCM_CPU_KERNELS=sse2 exited non-zero: $(cat "$OUT/k.log")"
grep -q "backend cpu (sse2 kernels)" "$OUT/k.log" || fail "bench does not name the sse2 kernels: $(head -1 "$OUT/k.log")"
if HPCM_CPU_KERNELS=neon "$HPCM" run --phantom 16,16,12 --frames 2 --out "$OUT/kbad" > "$OUT/kbad.log" 2>&1; then
  fail "HPCM_CPU_KERNELS=neon accepted"
fi
grep -q "HPCM_CPU_KERNELS='neon' is not one of sse2|avx2|avx512" "$OUT/kbad.log" || fail "HPCM_CPU_KERNELS message: $(cat "$OUT/kbad.log")"
echo "PASS"
