# Shared by the headless viewer tests (sourced): skips (exit 77) without xvfb-run, selects
# Mesa's software OpenGL, empties the output directory $OUT, defines fail and xrun.
if ! command -v xvfb-run >/dev/null 2>&1; then
  echo "SKIP: xvfb-run not found (install the Debian package xvfb)"
  exit 77
fi
export LIBGL_ALWAYS_SOFTWARE=1
mkdir -p "$OUT"
rm -rf "${OUT:?}"/*
fail() { echo "FAIL: $*"; exit 1; }
xrun() { xvfb-run -a -s "-screen 0 1280x800x24" "$VIEWER" "$@"; }
