#!/usr/bin/env bash
# Regenerates the golden states (tests/golden/*.csv) after a change that is meant to alter
# results: builds hpcm_test_golden and runs it with --regenerate, which writes every file from the
# reference configuration (CPU backend, sse2 kernels, 1 thread; the CUDA host emulation for its
# own files) and then checks every other kernel path and thread count against the new files, so a
# change that makes the paths disagree fails here too. Review `git diff tests/golden` and commit
# the files with the change. Needs ../shared/data for the abdomen run.
# Usage: scripts/regenerate_golden.sh [BUILD_DIR]   (default: build; configured Release when new)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-"$root/build"}
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build" -j"${JOBS:-2}" --target hpcm_test_golden
# The commit the files come from; "-dirty" when the change being regenerated is not committed yet.
commit=$(git -C "$root" describe --always --dirty --abbrev=12 2>/dev/null || echo "unknown (no git)")
"$build/tests/golden/hpcm_test_golden" --regenerate --commit="$commit" --golden-dir="$root/tests/golden"
git -C "$root" status --short -- tests/golden || true
