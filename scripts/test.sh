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
#
# Sized for a 2-core machine (docs/architecture.md, "The CI run": stage times and why no check
# is lost):
# - The ASan preset neither builds nor registers the `heavy` and `e2e` test executables
#   (HPCM_SKIP_TEST_LABELS; its test preset excludes the `e2e` script tests too), so it
#   compiles only what its own run executes. Its test preset also leaves to the Release stage,
#   by name, report_script (Python only), the stability rule's measured settling runs, three
#   NoFold simulations and the command-line runs on valid input, whose code the unit tests
#   run under ASan; the hostile-input tests stay.
# - Test sources compile at -O1 (Release) / -O0 (ASan) unless marked OPTIMIZED; the library
#   keeps its flags (HPCM_TEST_OPTIMIZATION, tests/CMakeLists.txt).
# - hpcm_cli, hpcm_test_core and the Python module are unity builds (every translation unit
#   compiled CLI11 / GoogleTest / pybind11 anew); the solver and backend libraries are not,
#   and keep their flags, so results stay bitwise the same (golden states).
# - The long tests carry a CTest COST (tests/CMakeLists.txt), so a fresh clone, which has no
#   CTestCostData.txt, starts them first and no core idles behind one at the end.
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
  # One job per harness: each run is time-boxed (HPCM_FUZZ_SECONDS of wall time), so on two
  # cores three runs of 30 s together get the core-seconds three runs of 20 s one after the
  # other got, with no core idle behind the third.
  ctest --preset fuzz -j 3
fi
if [ "${HPCM_SANITIZE:-1}" != 0 ]; then
  stage "ASan + UBSan build and test suite"
  cmake --preset asan
  cmake --build --preset asan -j "$JOBS"
  ctest --preset asan -j "$JOBS"  # the preset leaves out the labels heavy and e2e
fi
if [ "${HPCM_TSAN:-1}" != 0 ]; then
  stage "ThreadSanitizer build and threaded tests"
  cmake --preset tsan
  cmake --build --preset tsan -j "$JOBS"
  ctest --preset tsan -j "$JOBS"
fi
stage "done"
