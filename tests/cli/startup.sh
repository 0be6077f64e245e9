#!/usr/bin/env bash
# Start-up work is done only when needed: commands that read PNG or EXR files
# never load OpenImageIO (its ~260 libraries cost a process ~0.3 s of CPU);
# one that reads a TIFF does, which shows the check can see it. The loader's
# own trace (LD_DEBUG=files) says which libraries a process opened. Speed is
# measured by bench/startup_vs_opencv.py, never here.
. "$(dirname "$0")/lib.bash"

if ldd "$SETLIGHT" | grep -q libOpenImageIO; then
  skip "OpenImageIO is linked in (sanitizer build): nothing to check"
  finish
  exit
fi

"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" png "$T/env.png" 64 32 || bad "fixture"
"$SETLIGHT" convert "$T/env.exr" "$T/env.tif" 2>/dev/null || bad "fixture"

# loads_oiio CMD...: runs CMD (exit 0 expected) under the loader's trace;
# $T/libs lists the shared objects it opened.
loads_oiio() {
  expect 0 env LD_DEBUG=files LD_DEBUG_OUTPUT="$T/ld" "$@"
  cat "$T"/ld.* >"$T/libs" 2>/dev/null
  rm -f "$T"/ld.*
  grep -q 'file=.*libOpenImageIO' "$T/libs"
}
# not_loaded WHAT, loaded WHAT: the last loads_oiio's verdict.
not_loaded() { if [ "$1" -ne 0 ]; then ok; else bad "$2 loaded OpenImageIO"; fi; }
loaded() { if [ "$1" -eq 0 ]; then ok; else bad "$2 did not load OpenImageIO (is the trace working?)"; fi; }

loads_oiio "$SETLIGHT" info "$T/env.exr"; not_loaded $? "info on an EXR"
loads_oiio "$SETLIGHT" info "$T/env.png"; not_loaded $? "info on a PNG"
loads_oiio "$SETLIGHT" --version; not_loaded $? "--version"
# A 3-frame 8-bit PNG bracket, 2 stops apart, through a 1/2.2 gamma.
python3 - "$T" <<'PY' || bad "fixture"
import struct, sys, zlib
w, h = 48, 24
def chunk(t, d):
    return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
for k in range(3):
    rows = b"".join(b"\0" + bytes(min(255, round(255 * min(1.0, 2 ** (-7 + 9 * x / w + y / h + 2 * k)) ** (1 / 2.2)))
                                   for x in range(w) for c in range(3)) for y in range(h))
    hdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    open("%s/b%d.png" % (sys.argv[1], k), "wb").write(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", hdr) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
PY
loads_oiio "$SETLIGHT" merge --quiet --no-mask --times 1/16,1/4,1 -o "$T/m.exr" "$T/b0.png" "$T/b1.png" "$T/b2.png"
not_loaded $? "merge of a PNG bracket"
loads_oiio "$SETLIGHT" info "$T/env.tif"; loaded $? "info on a TIFF"

finish
