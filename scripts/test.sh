#!/usr/bin/env bash
# Builds hpcm (Release) and runs the whole test suite with CTest, then the guard rails of
# hostile input: the libFuzzer harnesses (clang, CMake preset "fuzz", each a bounded run) and
# the whole test suite again under ASan + UBSan (preset "asan"), and the tests of code that
# several threads run under ThreadSanitizer (preset "tsan", tests labelled `threads`).
# HPCM_FUZZ=0 / HPCM_SANITIZE=0 / HPCM_TSAN=0 leave those out (e.g. for a quick local run).
# Tests labelled `heavy` (minutes of simulation on paper-protocol lattices) run in the Release
# suite only: under the sanitizers they would take most of the CI budget and exercise no code
# the other tests do not.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
BUILD=${HPCM_BUILD_DIR:-build}
JOBS=$(nproc)
stage() { echo "== test.sh: $1 ($(date +%T))"; }
stage "Release build"
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD" -j "$JOBS"
stage "test suite"
ctest --test-dir "$BUILD" --output-on-failure -j "$JOBS"
if [ "${HPCM_FUZZ:-1}" != 0 ]; then
  stage "fuzz harnesses"
  cmake --preset fuzz
  cmake --build --preset fuzz -j "$JOBS"
  ctest --preset fuzz -j "$JOBS"
fi
if [ "${HPCM_SANITIZE:-1}" != 0 ]; then
  stage "ASan + UBSan build and test suite"
  cmake --preset asan
  cmake --build --preset asan -j "$JOBS"
  ctest --preset asan -j "$JOBS" -LE heavy
fi
if [ "${HPCM_TSAN:-1}" != 0 ]; then
  stage "ThreadSanitizer build and threaded tests"
  cmake --preset tsan
  cmake --build --preset tsan -j "$JOBS"
  ctest --preset tsan -j "$JOBS"
fi
stage "done"
