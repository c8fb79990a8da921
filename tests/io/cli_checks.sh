#!/usr/bin/env bash
# Command-line checks of issue 4: usage HPCM_BINARY DATA_DIR SCRATCH_DIR.
# Exit 77 (skipped) when the shared CT data is absent.
set -u
hpcm=$1 data=$2 out=$3
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$out" && mkdir -p "$out"

# Bad input: non-zero exit, one line on stderr, nothing on stdout.
"$hpcm" info /etc/hostname >"$out/stdout" 2>"$out/stderr"; rc=$?
[ $rc -ne 0 ] || fail "hpcm info /etc/hostname exited 0"
[ "$(wc -l <"$out/stderr")" -eq 1 ] || fail "expected one line on stderr, got: $(cat "$out/stderr")"
grep -q "unknown volume format" "$out/stderr" || fail "unexpected message: $(cat "$out/stderr")"
echo "ok: hpcm info /etc/hostname -> rc $rc: $(cat "$out/stderr")"

# Phantom written in a supported format and read back by info.
"$hpcm" phantom --size 24,20,16 --out "$out/ph.nrrd" >/dev/null || fail "hpcm phantom --out"
"$hpcm" info "$out/ph.nrrd" >"$out/info_ph.txt" || fail "hpcm info phantom"
grep -q "24x20x16" "$out/info_ph.txt" || fail "phantom dims: $(cat "$out/info_ph.txt")"
echo "ok: phantom --out + info"

if [ ! -d "$data/abdomen-ct-dicom" ] || [ ! -f "$data/abdomen-ct/abdomen_ct.nii.gz" ]; then
  echo "SKIP: $data is absent; real-data CLI checks not run"; exit 77
fi
"$hpcm" info "$data/abdomen-ct-dicom" >"$out/info.txt" || fail "hpcm info dicom"
grep -q "512x512x20" "$out/info.txt" || fail "dims: $(cat "$out/info.txt")"
read -r lo hi < <(awk '$1=="HU"{print $3, $5}' "$out/info.txt")
awk -v lo="$lo" -v hi="$hi" 'BEGIN{exit !(lo >= -1024 && hi <= 3071 && lo < hi)}' || fail "HU range $lo..$hi"
echo "ok: hpcm info dicom: 512x512x20, HU $lo..$hi"

"$hpcm" info "$data/abdomen-ct/abdomen_ct.nii.gz" --downsample 4 >"$out/info4.txt" || fail "info --downsample"
# Complete 4x4x4 blocks only: 122x101x112 -> 30x25x28.
grep -q "30x25x28 = 21000 elements" "$out/info4.txt" || fail "downsample: $(cat "$out/info4.txt")"
"$hpcm" info "$data/abdomen-ct/abdomen_ct.nii.gz" --downsample 200 2>"$out/err" && fail "--downsample 200 accepted"
[ "$(wc -l <"$out/err")" -eq 1 ] || fail "downsample error not one line"
echo "ok: info --downsample 4 and 200 ($(cat "$out/err"))"

# Full resolution (1.38 M elements), 2 frames: exports every frame and at the end.
"$hpcm" run --input "$data/abdomen-ct/abdomen_ct.nii.gz" --frames 2 --export-every 1 \
  --export "$out/export" --out "$out/run" >"$out/run.txt" 2>&1 || fail "run --export: $(cat "$out/run.txt")"
for f in displacement_0001.nii.gz displacement_0002.nii.gz displacement_final.nii.gz displacement_final.nrrd \
         deformed_0001.nii.gz deformed_final.nii.gz labels.nii.gz labels.ctbl; do
  [ -s "$out/export/$f" ] || fail "missing export $f"
done
# The NRRD header is text: a 3-component float vector image on the input's 3 mm grid.
hdr=$(head -c 1000 "$out/export/displacement_final.nrrd" | tr -d '\0')
grep -q "^type: float" <<<"$hdr" || fail "displacement type"
grep -q "^sizes: 3 122 101 112" <<<"$hdr" || fail "displacement sizes"
grep -q "^kinds: vector domain domain domain" <<<"$hdr" || fail "displacement kinds"
# On the input's own grid: the file is RAS-stored, so its first two axes run towards -L and -P.
grep -q "^space directions: none (-3,0,0) (0,-3,0) (0,0,3)" <<<"$hdr" || fail "displacement grid: $hdr"
grep -q "^displacement field type:=modeling" <<<"$hdr" || fail "displacement field type key missing"
"$hpcm" info "$out/export/deformed_final.nii.gz" >"$out/info_def.txt" || fail "deformed CT unreadable"
grep -q "122x101x112" "$out/info_def.txt" || fail "deformed CT not on the input grid"
"$hpcm" info "$out/export/displacement_final.nii.gz" 2>"$out/err" && fail "displacement read as CT"
grep -q "3 components" "$out/err" || fail "displacement field: $(cat "$out/err")"
echo "ok: run --export wrote $(ls "$out/export" | tr '\n' ' ')"
exit 0
