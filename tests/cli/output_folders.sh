#!/usr/bin/env bash
# Output folders and writes (issue 29): nothing a user asked for or put there is lost, every
# failed write is an error, and --out / --export nested in any way either work or are refused
# before anything runs.
# usage: output_folders.sh HPCM_BINARY SCRATCH_DIR
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)  # before any cd
HPCM=$1 OUT=$2
rm -rf "$OUT" && mkdir -p "$OUT"
cd "$OUT" || exit 1
source "$HERE/lib.sh" || exit 1
EXPORTS="displacement_final.nii.gz displacement_final.nrrd deformed_final.nii.gz labels.nii.gz labels.ctbl export.json"
has_exports() {  # has_exports DIR: every export file is there
  for f in $EXPORTS; do [ -s "$1/$f" ] || return 1; done
}
PH="--phantom 24,24,16 --frames 3"

# ---- the README's shape: --export inside --out --------------------------------------------------
"$HPCM" run $PH --export D/slicer --out D >readme.log 2>&1 || fail "README export example: $(cat readme.log)"
[ -s D/frames.csv ] || fail "D/frames.csv missing"
has_exports D/slicer || fail "exports missing from D/slicer: $(ls -R D)"
[ ! -e D.incomplete ] && [ ! -e D/slicer.incomplete ] || fail "staging folders left behind"
grep -q "exported to D/slicer" readme.log || fail "message does not name D/slicer: $(cat readme.log)"
"$HPCM" run $PH --export D/slicer --out D >readme2.log 2>&1 || fail "README example again: $(cat readme2.log)"
[ -s D/frames.csv ] && has_exports D/slicer || fail "second run lost files: $(ls -R D)"
ok "--export D/slicer --out D keeps frames.csv and every export, also when run again"

# ---- the same folder, and --out inside --export -------------------------------------------------
"$HPCM" run $PH --export same --out same >same.log 2>&1 || fail "--out same --export same: $(cat same.log)"
[ -s same/frames.csv ] && has_exports same || fail "same: $(ls same)"
"$HPCM" run $PH --out E/run --export E >nest.log 2>&1 || fail "--out E/run --export E: $(cat nest.log)"
[ -s E/run/frames.csv ] && has_exports E || fail "E: $(ls -R E)"
"$HPCM" run $PH --out apart_o --export apart_e >apart.log 2>&1 || fail "apart: $(cat apart.log)"
[ -s apart_o/frames.csv ] && has_exports apart_e || fail "apart folders"
ok "--out and --export equal, nested the other way, and apart all keep every file"
expect_error in_staging "one lies in the other's staging folder" "$HPCM" run $PH --out P --export P.incomplete/x
[ ! -e P ] && [ ! -e P.incomplete ] || fail "P created for a refused pair"

# ---- files a user added are never deleted -------------------------------------------------------
echo "my notes" >D/notes.txt
expect_error user_file "holds files hpcm did not write \(notes.txt\)" "$HPCM" run $PH --export D/slicer --out D
[ -f D/notes.txt ] && [ -s D/frames.csv ] && has_exports D/slicer || fail "the refused run touched D"
rm D/notes.txt
echo "mine" >D/slicer/seg.nii.gz
expect_error user_file_nested "slicer/seg.nii.gz" "$HPCM" run $PH --out D
[ -f D/slicer/seg.nii.gz ] || fail "a nested user file was deleted"
rm D/slicer/seg.nii.gz
mkdir -p old && printf 'hpcm output folder (finished run)\npid 1\n' >old/.hpcm-output && echo 1 >old/frames.csv
expect_error older_marker "does not list its files" "$HPCM" run $PH --out old
[ -f old/frames.csv ] || fail "an older output folder was deleted"
ok "an output folder with files hpcm did not write is refused, never emptied"

# ---- staging folders: a live hpcm is respected, a reused pid is not ------------------------------
sleep 60 &
other=$!
start=$(awk '{ sub(/.*\) /, ""); print $20 }' /proc/$other/stat)
mkdir -p busy.incomplete && printf 'hpcm output folder (in progress)\npid %s start %s\n' "$other" "$start" >busy.incomplete/.hpcm-output
expect_error live_writer "another hpcm \(process $other\) is writing" "$HPCM" run $PH --out busy
mkdir -p stale.incomplete && printf 'hpcm output folder (in progress)\npid %s start 1\n' "$other" >stale.incomplete/.hpcm-output
timeout 60 "$HPCM" run $PH --out stale >stale.log 2>&1 || fail "a stale staging folder whose pid now names another process blocked the run: $(cat stale.log)"
[ -s stale/frames.csv ] || fail "stale run wrote no frames.csv"
kill $other 2>/dev/null
ok "a staging folder of a live hpcm blocks, one whose pid was reused does not"

# ---- a symbolic link stays a link; no empty parents after a refused input; long names -------------
mkdir -p real && ln -s real link
"$HPCM" run $PH --out link >link.log 2>&1 || fail "--out link: $(cat link.log)"
"$HPCM" run $PH --out link >link2.log 2>&1 || fail "--out link again: $(cat link2.log)"
[ -L link ] && [ -s real/frames.csv ] || fail "--out through a symbolic link replaced the link"
ok "--out through a symbolic link writes into its folder and keeps the link"
echo "not a volume" >junk.nii.gz
expect_error junk_input "junk.nii.gz" "$HPCM" run --input junk.nii.gz --out p1/p2/p3
[ ! -e p1 ] || fail "empty parent folders left after a refused input: $(find p1)"
ok "no empty parent folders left behind by a refused input"
long=$(printf 'L%.0s' $(seq 250))
"$HPCM" run $PH --out "$long" >long.log 2>&1 || fail "a 250-character --out: $(cat long.log)"
[ -s "$long/frames.csv" ] || fail "no frames.csv in the 250-character folder"
ok "a 250-character --out works (staged under a shortened name)"

# ---- a file name that is not UTF-8 ----------------------------------------------------------------
bad=$'ph\xff.nii.gz'
"$HPCM" phantom --size 24,24,16 --out "$bad" >/dev/null || fail "phantom with a non-UTF-8 name"
"$HPCM" run --input "$bad" --frames 2 --export u8 --out u8 >u8.log 2>&1 || fail "run --input non-UTF-8: $(cat u8.log)"
has_exports u8 && grep -q "not valid UTF-8" u8.log || fail "non-UTF-8 input: $(cat u8.log)"
ok "an input path that is not UTF-8 runs to the end, recorded with U+FFFD and a warning"

# ---- a full disk (a file size limit) is an error, never a truncated file --------------------------
for ext in nii.gz nii nrrd nhdr mha mhd; do
  "$HPCM" phantom --size 64,64,48 --out "full.$ext" >/dev/null || fail "phantom full.$ext"
  bytes=$(cat full.* | wc -c)
  rm -f full.*
  # Half the bytes it needs; ignoring SIGXFSZ makes write() fail with EFBIG, as on a full disk.
  (trap '' XFSZ; ulimit -f $((bytes / 2048)); exec "$HPCM" phantom --size 64,64,48 --out "full.$ext") >fulllog.out 2>fulllog.err
  rc=$?
  [ $rc -ne 0 ] || fail "full.$ext: exit 0 on a write that cannot fit ($(ls -l full.* 2>&1))"
  grep -q "write failed\|cannot write" fulllog.err || fail "full.$ext: no write error: $(cat fulllog.err)"
  [ -z "$(ls full.* 2>/dev/null)" ] && [ -z "$(ls -A | grep hpcm-tmp)" ] || fail "full.$ext: left $(ls -A | grep 'full\.\|hpcm-tmp')"
  ok "full.$ext: $(grep -m1 "error" fulllog.err | cut -c1-140)"
done
(trap '' XFSZ; ulimit -f 64; exec "$HPCM" run --phantom 64,64,48 --frames 2 --export fx --out fo) >fx.out 2>fx.err
[ $? -ne 0 ] && grep -q "write failed\|cannot write" fx.err || fail "export under a file size limit: $(cat fx.err)"
[ ! -e fx ] && [ ! -e fo ] || fail "a failed export left a finished folder"
ok "an export that cannot be written fails and leaves no finished folder"
echo "all output-folder checks passed"
