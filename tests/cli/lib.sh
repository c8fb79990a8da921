# Shared by the command-line test scripts: source it after cd-ing into the scratch folder.
fail() { echo "FAIL: $*"; exit 1; }
ok() { echo "ok: $*"; }

# expect_error NAME PATTERN CMD...: exit 2 and one "hpcm: error: ..." line matching PATTERN,
# with nothing before it but notes and warnings (e.g. the --downsample note).
expect_error() {
  local name=$1 pattern=$2
  shift 2
  "$@" >"$name.out" 2>"$name.err"
  local rc=$?
  [ $rc -eq 2 ] || fail "$name: exit $rc (expected 2): $(head -3 "$name.err")"
  local line
  line=$(grep -m1 "^hpcm: error: " "$name.err") || fail "$name: no hpcm error line: $(head -3 "$name.err")"
  if sed '/^hpcm: error: /q' "$name.err" | sed '$d' | grep -qvE '^(note|hpcm: warning): '; then
    fail "$name: other output before the error line: $(head -3 "$name.err")"
  fi
  echo "$line" | grep -qE -- "$pattern" || fail "$name: '$pattern' not in: $line"
  ok "$name: $(echo "$line" | cut -c1-160)"
}
