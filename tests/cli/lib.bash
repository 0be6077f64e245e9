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
# sky_hdr FILE EXP: a 32 x 16 Radiance lat-long, a sky of 1.0 (blue 1.25)
# with one bright texel (10, 4) of 255 x 2^(EXP - 136).
sky_hdr() {
  python3 - "$1" "$2" <<'PY'
import sys
w, h, e = 32, 16, int(sys.argv[2])
with open(sys.argv[1], "wb") as f:
    f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w))
    for y in range(h):
        for x in range(w):
            f.write(bytes([255, 255, 255, e]) if (x, y) == (10, 4) else bytes([128, 128, 160, 129]))
PY
}
# png_bracket DIR W H: DIR/br_0.png .. br_2.png, 8-bit sRGB-ish PNGs (gamma
# 1/2.2) of a smooth scene at gains 1/4, 1 and 4 (two stops apart).
png_bracket() {
  python3 - "$@" <<'PY'
import struct, sys, zlib
d, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def chunk(t, data):
    c = struct.pack(">I", len(data)) + t + data
    return c + struct.pack(">I", zlib.crc32(t + data) & 0xffffffff)
for k, gain in enumerate((0.25, 1.0, 4.0)):
    rows = [bytes(int(round(min(1.0, 2 ** (-6 + 10 * (0.6 * (x + 0.5) / w + 0.4 * (y + 0.5) / h)) * gain) ** (1 / 2.2) * 255))
                  for x in range(w) for c in range(3)) for y in range(h)]
    raw = b"".join(b"\0" + r for r in rows)
    hdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    open("%s/br_%d.png" % (d, k), "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", hdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
PY
}
finish() {
  echo "$passed passed, $failed failed, $skipped skipped"
  [ "$failed" -eq 0 ]
}
# browser_check PAGE.html MIN_IMAGES: the page opens in a real browser
# (headless Chromium) with at least MIN_IMAGES images and plots, none of them
# missing or unreadable, and its screenshot is a real picture.
browser_check() {
  local page=$1 min=$2 browser
  browser=$(command -v chromium-headless-shell || command -v chromium || true)
  if [ -z "$browser" ]; then skip "browser check of $page (no chromium-headless-shell)"; return; fi
  local probe
  probe="$(dirname "$page")/.browser_check_$$.html"
  { cat "$page"
    echo '<script>window.addEventListener("load",()=>{const i=[...document.images];'
    echo 'const b=i.filter(e=>!e.complete||!e.naturalWidth).map(e=>e.getAttribute("src"));'
    echo 'document.body.insertAdjacentHTML("beforeend","<pre id=\"sl-check\">images="+i.length+" broken="+b.join(",")+";</pre>")});</script>'
  } >"$probe"
  local flags=(--no-sandbox --disable-gpu --allow-file-access-from-files --virtual-time-budget=10000)
  local dom
  dom=$(timeout 120 "$browser" "${flags[@]}" --dump-dom "file://$(realpath "$probe")" 2>/dev/null)
  timeout 120 "$browser" "${flags[@]}" --window-size=1100,1400 --screenshot="$T/browser_shot.png" \
    "file://$(realpath "$page")" >/dev/null 2>&1
  rm -f "$probe"
  local line n broken
  line=$(printf '%s' "$dom" | grep -o 'images=[0-9]* broken=[^;]*;' | tail -1)
  n=$(printf '%s' "$line" | sed 's/images=\([0-9]*\).*/\1/')
  broken=$(printf '%s' "$line" | sed 's/.*broken=\([^;]*\);/\1/')
  if [ -z "$line" ]; then bad "$page did not load in the browser"
  elif [ -n "$broken" ]; then bad "$page: images missing in the browser: $broken"
  elif [ "$n" -lt "$min" ]; then bad "$page shows $n images, want at least $min"
  else ok; fi
  # a blank page compresses to almost nothing
  if [ -s "$T/browser_shot.png" ] && [ "$(stat -c %s "$T/browser_shot.png")" -gt 20000 ]; then ok
  else bad "$page: the browser's screenshot is missing or blank"; fi
}
