#!/usr/bin/env bash
# The main job: the paper protocol (conditions A/B/C) on the built-in synthetic phantom.
# Writes tables, the behaviour checks, figures and report.md to ${1:-out/experiment}.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
BUILD=${HPCM_BUILD_DIR:-build}
OUT=${1:-out/experiment}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD" -j "$(nproc)" --target hpcm_cli
"$BUILD/apps/hpcm/hpcm" experiment --phantom "${HPCM_PHANTOM:-96,96,64}" --out "$OUT"
echo "report: $OUT/report.md"
