#!/usr/bin/env bash
# Builds hpcm (Release) and runs the whole test suite with CTest, then the guard rails of
# hostile input: the libFuzzer harnesses (clang, CMake preset "fuzz", each a bounded run), the
# unit tests and the hostile-input command-line tests again under ASan + UBSan (preset "asan",
# built at -O1 with line tables: half the compile time of -O2 -g, and reports still name the
# line), and the tests of code that several threads run under ThreadSanitizer (preset "tsan",
# tests labelled `threads`). HPCM_FUZZ=0 / HPCM_SANITIZE=0 / HPCM_TSAN=0 leave those out (e.g.
# for a quick local run). Tests labelled `heavy` (minutes of simulation on paper-protocol
# lattices) and `e2e` (whole experiments and tool runs checked for their figures, the viewer)
# run in the Release suite only: they reach no code the unit tests do not, and under the
# sanitizers they would take most of the CI budget.
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
  ctest --preset asan -j "$JOBS" -LE "heavy|e2e"
fi
if [ "${HPCM_TSAN:-1}" != 0 ]; then
  stage "ThreadSanitizer build and threaded tests"
  cmake --preset tsan
  cmake --build --preset tsan -j "$JOBS"
  ctest --preset tsan -j "$JOBS"
fi
stage "done"
