# Shared helpers for the CLI tests (sourced, not run). Each test script gets
# $SETLIGHT, $MAKE_FIXTURE, $SETLIGHT_TEST_TMP and $SETLIGHT_SHARED_DATA from ctest.
set -u
passed=0
failed=0
skipped=0
name=$(basename "$0" .sh)
T="${SETLIGHT_TEST_TMP:-/tmp}/cli_$name"
rm -rf "$T"
mkdir -p "$T"

ok() { passed=$((passed + 1)); }
bad() { failed=$((failed + 1)); echo "FAILED: $*"; }
skip() { skipped=$((skipped + 1)); echo "skip $*"; }

# expect CODE CMD...: runs CMD, keeps stdout in $T/out and stderr in $T/err,
# checks the exit code.
expect() {
  local want=$1
  shift
  "$@" >"$T/out" 2>"$T/err"
  local got=$?
  if [ "$got" -eq "$want" ]; then ok; else bad "exit $got (want $want): $* :: $(head -c 400 "$T/err")"; fi
}
# err_has TEXT: stderr of the last command contains TEXT.
err_has() { if grep -qF -- "$1" "$T/err"; then ok; else bad "stderr lacks '$1': $(head -c 400 "$T/err")"; fi; }
out_has() { if grep -qF -- "$1" "$T/out"; then ok; else bad "stdout lacks '$1': $(head -c 400 "$T/out")"; fi; }
# err_one_line: the error message is exactly one line.
err_one_line() { local n; n=$(wc -l <"$T/err"); if [ "$n" -eq 1 ]; then ok; else bad "stderr has $n lines: $(head -c 400 "$T/err")"; fi; }
absent() { if [ ! -e "$1" ]; then ok; else bad "$1 exists but should not"; fi; }
present() { if [ -s "$1" ]; then ok; else bad "$1 missing or empty"; fi; }
# no_temp DIR: no temporary output left behind.
no_temp() { if ls -a "$1" | grep -q 'sl-tmp'; then bad "temporary file left in $1"; else ok; fi; }
json_ok() { if python3 -c 'import json,sys; json.load(open(sys.argv[1]))' "$1" 2>/dev/null; then ok; else bad "not JSON: $(head -c 300 "$1")"; fi; }
# json_eval FILE EXPR: python expression over `d` (the parsed JSON) must be true.
json_eval() {
  if python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' "$1" "$2"; then ok
  else bad "JSON check failed: $2 on $(head -c 300 "$1")"; fi
}
finish() {
  echo "$passed passed, $failed failed, $skipped skipped"
  [ "$failed" -eq 0 ]
}
