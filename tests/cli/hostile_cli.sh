#!/usr/bin/env bash
# Hostile input against the hpcm command line (issue 15): every case must end in a clear error
# (exit 2, one hpcm line first, naming the option/file/value) or in the right answer, never in
# a wrong answer with exit 0.
# usage: hostile_cli.sh HPCM_BINARY SOURCE_DIR DATA_DIR SCRATCH_DIR
# Parts that need /usr/bin/python3 with pydicom (DICOM tag edits) or the shared data say SKIP
# and are left out; everything else always runs.
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)  # before any cd
HPCM=$1 SRC=$2 DATA=$3 OUT=$4
rm -rf "$OUT" && mkdir -p "$OUT"
cd "$OUT" || exit 1
source "$HERE/lib.sh" || exit 1

# ---- 1. no shell ------------------------------------------------------------------------------
# The tree has no system()/popen() call (helper programs start with an argument vector).
if grep -rnE '(std::|[^_a-z])(system|popen)\(' "$SRC/src" "$SRC/apps" "$SRC/include" --include=*.cpp --include=*.hpp \
     --include=*.cu >shell_calls.txt; then
  fail "shell calls in the source: $(cat shell_calls.txt)"
fi
ok "no system()/popen() in src/, apps/, include/"
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  bad="$OUT/x';touch $OUT/PWNED;'"
  "$HPCM" experiment --phantom 24,24,16 --settle-frames 5 --out "$bad" >exp.log 2>&1 || fail "experiment with quotes in --out: $(cat exp.log)"
  [ ! -e "$OUT/PWNED" ] || fail "shell injection: --out ran a command"
  [ -s "$bad/report.md" ] && [ -s "$bad/figure3.png" ] || fail "report not written for an --out with quotes"
  ok "experiment --out with quotes and ';': no command ran, report written"
  # Work per frame: one row per protocol frame and condition, plotted in figure 5.
  [ "$(wc -l <"$bad/activity.csv")" -eq 451 ] || fail "activity.csv: expected a header and 3 x 150 rows, got $(wc -l <"$bad/activity.csv") lines"
  [ -s "$bad/figure5.png" ] && grep -q "Figure 5" "$bad/report.md" || fail "figure 5 (active elements per frame) missing from the report"
  ok "experiment writes activity.csv (3 x 150 frames) and plots it in figure 5"
else
  echo "SKIP: /usr/bin/python3 without matplotlib: report-script injection case not run"
fi

# ---- 2. integer options: exact, range-checked, checked before any folder is made --------------
expect_error roi_wrap "--roi .*4294967328 is out of range" "$HPCM" run --phantom 24,24,16 --roi 0,0,0,4294967328,20,16 --out o_roi
expect_error frames_sentinel "--frames -1000000 is out of range \(valid: an integer in \[1, 10000000\]\)" \
  "$HPCM" run --phantom 24,24,16 --frames -1000000 --out o_frames
expect_error frames_zero "--frames 0 is out of range" "$HPCM" run --phantom 24,24,16 --frames 0 --out o_frames
expect_error frames_junk "--frames '12abc' is not an integer" "$HPCM" run --phantom 24,24,16 --frames 12abc --out o_frames
expect_error downsample_wrap "--downsample 4294967297 is out of range" "$HPCM" run --phantom 24,24,16 --downsample 4294967297 --out o_ds
expect_error seed_negative "--seed -1 is out of range" "$HPCM" phantom --size 24,24,16 --seed -1 --summary
expect_error seed_overflow "--seed 18446744073709551616 is out of range" "$HPCM" phantom --size 24,24,16 --seed 18446744073709551616 --summary
expect_error settle_negative "--settle-frames -5 is out of range" "$HPCM" experiment --phantom 24,24,16 --settle-frames -5 --out o_exp
expect_error phantom_size "--size .*99999999999 is out of range" "$HPCM" phantom --size 24,24,99999999999 --summary
"$HPCM" info --phantom 24,24,16 --seed 18446744073709551615 | grep -q "seed 18446744073709551615" || fail "largest seed not kept"
for d in o_roi o_frames o_ds o_exp; do [ ! -e "$d" ] && [ ! -e "$d.incomplete" ] || fail "$d created before the options were checked"; done
ok "no output folder created by a rejected command"

# ---- 3. parameter files: directories, /dev/zero --------------------------------------------------
mkdir -p pdir
expect_error params_dir "pdir: is a directory, not a parameter file" "$HPCM" params --check pdir
expect_error params_dir_run "pdir: is a directory" "$HPCM" run --phantom 24,24,16 --params pdir --out o_p
expect_error params_dev_zero "/dev/zero: is not a regular file" timeout 20 "$HPCM" params --check /dev/zero
expect_error scenario_dir "pdir: is a directory, not a scenario file" "$HPCM" params --check-scenario pdir

# ---- 4. output folders: staged, never mixed, unwritable found first ------------------------------
"$HPCM" run --phantom 24,24,16 --frames 6 --out r >/dev/null 2>&1 || fail "run into r"
"$HPCM" run --phantom 24,24,16 --frames 4 --out r >/dev/null 2>&1 || fail "re-run into r"
[ "$(($(wc -l <r/frames.csv) - 1))" -eq 4 ] || fail "re-run frames.csv has $(wc -l <r/frames.csv) lines"
[ ! -e r.incomplete ] || fail "staging folder left after a finished run"
ok "re-run replaces the earlier output folder as a whole"
mkdir -p mine && echo notes >mine/notes.txt
expect_error foreign_folder "holds files hpcm did not write" "$HPCM" run --phantom 24,24,16 --frames 3 --out mine
[ -f mine/notes.txt ] || fail "a foreign folder was touched"
start=$(date +%s%N)
expect_error unwritable_out "--out /dev/null/x: cannot create the parent folder" "$HPCM" run --phantom 128,128,75 --out /dev/null/x
expect_error unwritable_export "--export /dev/null/y" "$HPCM" run --phantom 128,128,75 --export /dev/null/y --out o_ex
[ $(( ($(date +%s%N) - start) / 1000000 )) -lt 5000 ] || fail "unwritable destinations found only after a simulation"
[ ! -e o_ex ] && [ ! -e o_ex.incomplete ] || fail "--out staging left after a refused --export"
# A killed run leaves OUT.incomplete with every frame it computed (rows are streamed), never OUT.
"$HPCM" run --phantom 40,40,30 --frames 1000000 --no-link-check --out killed >/dev/null 2>&1 &
pid=$!
for _ in $(seq 100); do
  [ -f killed.incomplete/frames.csv ] && [ "$(wc -l <killed.incomplete/frames.csv)" -ge 4 ] && break
  sleep 0.1
done
kill -9 $pid
wait $pid 2>/dev/null
[ ! -e killed ] || fail "a killed run produced its final folder"
rows=$(($(wc -l <killed.incomplete/frames.csv) - 1))
[ "$rows" -ge 3 ] || fail "killed run kept $rows frames"
awk -F, 'NR == 1 { n = NF } NR > 1 && NF != n { bad = 1 } END { exit bad }' killed.incomplete/frames.csv || fail "killed run left a half row"
"$HPCM" run --phantom 24,24,16 --frames 3 --out killed >/dev/null 2>&1 || fail "run after a killed run"
[ ! -e killed.incomplete ] || fail "the killed run's staging folder survived the next run"
ok "killed run kept $rows frames in killed.incomplete/frames.csv; the next run replaced it"

# ---- 5. memory estimate before allocating ---------------------------------------------------------
start=$(date +%s%N)
expect_error memory "a lattice of 2000x2000x500 = 2000000000 elements needs about 320.00 GB" \
  "$HPCM" run --phantom 2000,2000,500 --frames 1 --out o_mem
[ $(( ($(date +%s%N) - start) / 1000000 )) -lt 5000 ] || fail "memory refusal was not immediate"
[ ! -e o_mem ] && [ ! -e o_mem.incomplete ] || fail "o_mem created for a refused lattice"

# ---- 6. outputs never share a data file; no non-finite value in frames.csv -----------------------
"$HPCM" phantom --size 16,16,12 --seed 1 --out a.nhdr >/dev/null || fail "phantom a.nhdr"
cp a.raw a.raw.orig
expect_error shared_raw "a.mhd: its data file a.raw already exists and belongs to a.nhdr" \
  "$HPCM" phantom --size 16,16,12 --seed 2 --out a.mhd
cmp -s a.raw a.raw.orig || fail "a.raw changed"
[ ! -e a.mhd ] || fail "a.mhd written"
"$HPCM" run --phantom 24,24,16 --frames 40 --out fin >/dev/null || fail "run fin"
if grep -qiE 'nan|inf' fin/frames.csv; then fail "non-finite value in frames.csv"; fi
ok "frames.csv holds only finite numbers"

# ---- 7. scenarios: errors name the file and the grab ------------------------------------------------
cat >far.toml <<'EOF'
[scenario]
frames = 10
[[grab]]
centre = [100, 100, 100]
release = 5
keyframes = [[5, 0, -2, 0]]
EOF
"$HPCM" params --check-scenario far.toml >/dev/null || fail "far.toml should pass --check-scenario (no lattice yet)"
expect_error scenario_far "scenario far.toml.*grab\[0\]\.centre \(100,100,100\) is outside the lattice 24x24x16" \
  "$HPCM" run --phantom 24,24,16 --scenario far.toml --out o_far
[ ! -e o_far ] || fail "o_far created by a failed run"
cat >huge.toml <<'EOF'
[scenario]
frames = 30
[[grab]]
centre = [10, 10, 8]
release = 20
keyframes = [[5, 3e38, 0, 0], [10, -3e38, 0, 0]]
EOF
expect_error scenario_huge "huge.toml: grab\[0\]\.keyframes\[0\]\[1\] \(dx\) = .* out of range" "$HPCM" params --check-scenario huge.toml

# ---- 8. volume files: spacing, non-finite voxels, HU ------------------------------------------------
mkvol() { /usr/bin/python3 "$SRC/tests/io/make_bad_volume.py" "$1" "$2" || fail "make_bad_volume $1"; }
for c in "nifti_nan nii non-finite values" "nifti_inf nii.gz non-finite values" \
         "nifti_pixdim_zero nii pixdim\[1\] \(x\) = 0 is not a positive number" \
         "nifti_pixdim_nan nii.gz pixdim\[1\] \(x\) = nan is not a positive number" \
         "nifti_pixdim_negative nii pixdim\[1\] \(x\) = -2" \
         "mha_spacing_zero mha ElementSpacing\[0\] = 0 is not a positive number" \
         "mha_spacing_nan mha ElementSpacing\[0\] = nan" "mha_spacing_negative mha ElementSpacing\[0\] = -2" \
         "nrrd_spacing_zero nrrd spacings\[0\] = 0 is not a positive number" "nrrd_spacing_nan nrrd spacings\[0\] = nan" \
         "nrrd_direction_nan nrrd space directions of axis 0" "nifti_hu_huge nii are not Hounsfield units"; do
  read -r name ext pattern <<<"$c"
  mkvol "$name" "$name.$ext"
  expect_error "$name" "$name.$ext: .*$pattern" "$HPCM" info "$name.$ext"
done
mkvol nifti_hu_padding pad.nii
"$HPCM" info pad.nii >pad.out 2>pad.err || fail "padding HU refused: $(cat pad.err)"
grep -q "^hpcm: warning: pad.nii: 1 voxels lie outside \[-4096, 32767\] HU" pad.err || fail "no HU warning: $(cat pad.err)"
for good in nifti_ok:nii mha_ok:mha nrrd_ok:nrrd; do
  mkvol "${good%%:*}" "g.${good##*:}"
  "$HPCM" info "g.${good##*:}" 2>/dev/null | grep -q "^spacing    2 x 2 x 2 mm" || fail "valid ${good##*:} not read with 2 mm"
done
ok "valid NIfTI, MetaImage and NRRD files still read with their 2 mm spacing"

# ---- 9. DICOM series built from the shared series --------------------------------------------------
if [ ! -d "$DATA/abdomen-ct-dicom" ]; then
  echo "SKIP: $DATA/abdomen-ct-dicom is absent: DICOM cases not run"
elif ! /usr/bin/python3 -c "import pydicom" 2>/dev/null; then
  echo "SKIP: /usr/bin/python3 has no pydicom (Debian python3-pydicom): DICOM cases not run"
else
  mk() { /usr/bin/python3 "$SRC/tests/io/make_bad_dicom.py" "$1" "$DATA/abdomen-ct-dicom" "dcm_$1" >/dev/null 2>&1 || fail "make_bad_dicom $1"; }
  for c in "duplicate 2 slices at the same position -784.5 mm" \
           "missing slices are not evenly spaced: .* are 4 mm apart where the series' usual step is 2 mm \(1 slice\(s\) missing\?\)" \
           "moved slices are not evenly spaced: .* 3 mm apart" \
           "random_bytes 1 file is not readable DICOM: CT\." \
           "stray_file 1 file is not readable DICOM: notes.txt" \
           "same_position all 20 slices are at the same position" \
           "oblique mixed slice orientations" \
           "no_position has no ImagePositionPatient \(0020,0032\)" \
           "zero_spacing PixelSpacing \(0028,0030\) = '0.0.0.0' is not a positive spacing" \
           "nan_spacing PixelSpacing \(0028,0030\) = 'NaN.NaN'" \
           "other_size mixed image sizes" \
           "truncated cannot read the pixels of CT\."; do
    read -r name pattern <<<"$c"
    mk "$name"
    expect_error "dicom_$name" "dcm_$name: .*$pattern" "$HPCM" info "dcm_$name"
  done
  # Library noise comes after hpcm's line, as indented detail.
  grep -q "^  library output while reading:" dicom_truncated.err || fail "truncated: no library detail: $(cat dicom_truncated.err)"
  "$HPCM" info --input dcm_duplicate --dicom-duplicates first >dup.out 2>dup.err || fail "--dicom-duplicates first: $(cat dup.err)"
  grep -q "^spacing    0.976562 x 0.976562 x 2 mm" dup.out && grep -q "^dims       512x512x20" dup.out \
    || fail "--dicom-duplicates first: $(cat dup.out)"
  grep -q "left out 1 slice" dup.err || fail "--dicom-duplicates first: no warning"
  "$HPCM" info --input dcm_stray_file --dicom-skip-unreadable >stray.out 2>stray.err || fail "--dicom-skip-unreadable"
  grep -q "skipped (--dicom-skip-unreadable): 1 file is not readable DICOM: notes.txt" stray.err || fail "no skip warning"
  expect_error dicom_skip_gap "not evenly spaced" "$HPCM" info --input dcm_random_bytes --dicom-skip-unreadable
  ok "DICOM opt-ins: --dicom-duplicates first reads 20 slices at 2 mm; --dicom-skip-unreadable never hides a gap"
fi
echo "PASS"
