#!/usr/bin/env bash
# Parameter, scenario and lattice limits of the hpcm command line (issue 29, item 15): each
# case ends in a clear error (exit 2, naming the file, value or lattice and the limit), never
# in a run that ignores the input or dies later.
# usage: core_limits_cli.sh HPCM_BINARY DATA_DIR SCRATCH_DIR
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)  # before any cd
HPCM=$1 DATA=$2 OUT=$3
rm -rf "$OUT" && mkdir -p "$OUT"
cd "$OUT" || exit 1
source "$HERE/lib.sh" || exit 1

# 1. phantom --params is validated even when only --out is written.
printf '[dynamics]\nalpha = 1.5\n' >bad.toml
expect_error phantom_bad_params "bad.toml: dynamics.alpha = 1.5 is out of range" \
  "$HPCM" phantom --size 16,16,12 --params bad.toml --out ph.nrrd
[ ! -e ph.nrrd ] || fail "phantom wrote its volume despite a bad --params file"

# 2. A number below the smallest positive float is refused, not read as 0.
printf '[dynamics]\nalpha = 1e-50\n' >tiny.toml
expect_error params_underflow "tiny.toml: dynamics.alpha = 1e-50 is below the smallest positive single-precision value" \
  "$HPCM" params --check tiny.toml

# 3. A FIFO as parameter or scenario file is refused before it is opened (no hang).
mkfifo fifo.toml
expect_error params_fifo "fifo.toml: is not a regular file" timeout 20 "$HPCM" params --check fifo.toml
expect_error scenario_fifo "fifo.toml: is not a regular file" timeout 20 "$HPCM" run --phantom 16,16,12 --scenario fifo.toml --out o_fifo

# 4. Lattices too small for the grab are refused with the minimum (5 per axis at radius 1.5).
expect_error lattice_flat "needs a lattice of at least 5 elements along every axis .* the lattice is 32x32x1" \
  "$HPCM" run --phantom 64,64,64 --roi 0,0,0,32,32,1 --frames 5 --out o_flat
expect_error lattice_one "needs a lattice of at least 5 elements along every axis .* the lattice is 1x1x1" \
  "$HPCM" run --phantom 64,64,64 --roi 0,0,0,1,1,1 --frames 5 --out o_one
printf '[solver]\ngrab_radius = 3.0\n' >r3.toml
expect_error lattice_radius "grab radius 3\) needs a lattice of at least 9 elements .* the lattice is 16x16x8" \
  "$HPCM" run --phantom 16,16,8 --frames 5 --params r3.toml --out o_r3
CT="$DATA/abdomen-ct/abdomen_ct.nii.gz"
if [ -f "$CT" ]; then
  expect_error ct_downsample_24 "needs a lattice of at least 5 elements along every axis .* the lattice is 5x4x4" \
    "$HPCM" run --input "$CT" --downsample 24 --frames 5 --out o_ds24
else
  echo "SKIP: $CT not found: --downsample 24 case not run"
fi

# 5. The memory check counts the address-space limit (ulimit -v): refused up front, naming both.
# AddressSanitizer reserves terabytes of address space for its shadow memory at start-up, so an
# ASan build cannot run under a 4 GB ulimit -v at all: the case runs in the other builds.
if ldd "$HPCM" 2>/dev/null | grep -q libasan; then
  echo "SKIP: ulimit -v case (an AddressSanitizer build cannot start under an address-space limit)"
else
  expect_error ulimit_v "needs about 10.24 GB .* of memory are available and the address-space limit \(ulimit -v, RLIMIT_AS\) leaves" \
    timeout 60 bash -c 'ulimit -v 4000000 && exec "$0" "$@"' "$HPCM" run --phantom 400,400,400 --frames 2 --out o_big
fi
for d in o_fifo o_flat o_one o_r3 o_ds24 o_big; do [ ! -e "$d" ] || fail "$d was created by a refused run"; done
echo "PASS"
