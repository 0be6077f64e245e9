#!/usr/bin/env bash
# Start-up work is done only when needed: commands that read PNG, JPEG, TIFF or EXR
# files never load OpenImageIO (its ~260 libraries cost a process ~0.35 s of CPU)
# nor OpenCV (ball and chart detection only; ~11 ms); one that reads a palette
# TIFF (left to OpenImageIO) loads it, which shows the check can see it. The loader's own trace
# (LD_DEBUG=files) says which libraries a process opened. Speed is measured
# by bench/startup_vs_opencv.py, never here.
. "$(dirname "$0")/lib.bash"

# A TIFF cut short or garbled (libtiff's reading): one line naming the file, exit 3,
# nothing written.
"$MAKE_FIXTURE" latlong "$T/tif.exr" 64 32 || bad "fixture"
"$SETLIGHT" convert "$T/tif.exr" "$T/good.tif" 2>/dev/null || bad "fixture"
head -c 200 "$T/good.tif" >"$T/cut.tif"
python3 -c 'import sys; b = bytearray(open(sys.argv[1], "rb").read()); b[8:40] = b"\xa5" * 32; open(sys.argv[2], "wb").write(b)' \
  "$T/good.tif" "$T/garbled.tif" || bad "fixture"
for f in cut garbled; do
  p="$T/$f.tif"
  expect 3 "$SETLIGHT" info "$p"; err_has "setlight info: $p: truncated or corrupt"; err_one_line
  expect 3 "$SETLIGHT" convert "$p" "$T/${f}_c.exr"; err_has "setlight convert: $p: "; err_one_line
  absent "$T/${f}_c.exr"
  expect 3 "$SETLIGHT" merge --quiet --times 1,2 -o "$T/${f}_m.exr" "$T/good.tif" "$p"
  err_has "setlight merge: $p: "; err_one_line
  absent "$T/${f}_m.exr"
done
no_temp "$T"

# Sanitizer builds link OpenImageIO and OpenCV in (CMakeLists.txt).
if ldd "$SETLIGHT" | grep -q 'libasan'; then
  skip "sanitizer build: OpenImageIO and OpenCV are linked in"
  finish
  exit
fi

"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" png "$T/env.png" 64 32 || bad "fixture"
"$SETLIGHT" convert "$T/env.exr" "$T/env.tif" 2>/dev/null || bad "fixture"

# trace CMD...: runs CMD (exit 0 expected) under the loader's trace; $T/libs
# lists the shared objects it opened.
trace() {
  expect 0 env LD_DEBUG=files LD_DEBUG_OUTPUT="$T/ld" "$@"
  cat "$T"/ld.* >"$T/libs" 2>/dev/null
  rm -f "$T"/ld.*
}
# lean WHAT: the last traced command loaded neither OpenImageIO nor OpenCV.
lean() {
  if grep -q 'file=.*libOpenImageIO' "$T/libs"; then bad "$1 loaded OpenImageIO"; else ok; fi
  if grep -q 'file=.*libopencv' "$T/libs"; then bad "$1 loaded OpenCV"; else ok; fi
}

trace "$SETLIGHT" info "$T/env.exr"; lean "info on an EXR"
trace "$SETLIGHT" info "$T/env.png"; lean "info on a PNG"
trace "$SETLIGHT" --version; lean "--version"
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
trace "$SETLIGHT" merge --quiet --no-mask --times 1/16,1/4,1 -o "$T/m.exr" "$T/b0.png" "$T/b1.png" "$T/b2.png"
lean "merge of a PNG bracket"
# JPEG: libjpeg, not OpenImageIO (a JPEG with XMP or CMYK would load it).
"$SETLIGHT" convert "$T/env.exr" "$T/env.jpg" 2>/dev/null || bad "fixture"
for k in 0 1 2; do
  "$SETLIGHT" convert "$T/b$k.png" "$T/b$k.jpg" 2>/dev/null || bad "fixture"
done
trace "$SETLIGHT" info "$T/env.jpg"; lean "info on a JPEG"
trace "$SETLIGHT" merge --quiet --no-mask --times 1/16,1/4,1 -o "$T/mj.exr" "$T/b0.jpg" "$T/b1.jpg" "$T/b2.jpg"
lean "merge of a JPEG bracket"
# TIFF: libtiff, not OpenImageIO: a float TIFF, and the virtual set's 16-bit
# frames through the camera curve and linear with an ICC profile, read and merged.
trace "$SETLIGHT" info "$T/env.tif"; lean "info on a TIFF"
"$SETLIGHT" simulate --scene exterior --size tiny --out "$T/vs" >/dev/null 2>&1 || bad "fixture"
trace "$SETLIGHT" info "$T/vs/hdri/IMG_0001_linear.tif"; lean "info on a linear TIFF"
grep -q 'lin_rec709' "$T/out" && ok || bad "the linear TIFF's ICC profile not read: $(cat "$T/out")"
frames=("$T"/vs/hdri/IMG_000[1-7].tif)
trace "$SETLIGHT" merge --quiet --json -o "$T/mt.exr" "${frames[@]}"; lean "merge of a TIFF bracket"
linear=("$T"/vs/hdri/IMG_000[1-7]_linear.tif)
trace "$SETLIGHT" merge --quiet -o "$T/ml.exr" "${linear[@]}"; lean "merge of a linear TIFF bracket"
# A palette TIFF is OpenImageIO's: the trace sees it loaded.
python3 - "$T/pal.tif" <<'PY' || bad "fixture"
import struct, sys
w, h = 4, 2
pix = bytes(range(w * h))
cmap = b"".join(struct.pack("<H", (i * 257) % 65536) for i in range(256)) * 3
entries = [(256, 3, 1, w), (257, 3, 1, h), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 3),
           (273, 4, 1, 0), (277, 3, 1, 1), (278, 3, 1, h), (279, 4, 1, len(pix)), (320, 3, 768, 0)]
ifd = 8
data = ifd + 2 + 12 * len(entries) + 4
out = bytearray(b"II*\0" + struct.pack("<I", ifd) + struct.pack("<H", len(entries)))
tail = bytearray()
for tag, typ, n, v in entries:
    if tag == 273: v = data
    if tag == 320: v = data + len(pix)
    out += struct.pack("<HHI", tag, typ, n) + (struct.pack("<HH", v, 0) if typ == 3 and n == 1 else struct.pack("<I", v))
out += b"\0\0\0\0" + pix + cmap
open(sys.argv[1], "wb").write(out)
PY
trace "$SETLIGHT" info "$T/pal.tif"
if grep -q 'file=.*libOpenImageIO' "$T/libs"; then ok; else bad "info on a palette TIFF did not load OpenImageIO (is the trace working?)"; fi
# Ball detection loads OpenCV (and still finds the ball through the module).
"$MAKE_FIXTURE" ball "$T/ball.exr" || bad "fixture"
trace "$SETLIGHT" unwrap --json --focal-mm 18 --sensor-mm 20 -o "$T/u.exr" "$T/ball.exr"
json_eval "$T/out" 'd["circle"]["detected"] and abs(d["circle"]["r"] - 46.5) < 0.5'
if grep -q 'file=.*libopencv' "$T/libs"; then ok; else bad "ball detection did not load OpenCV"; fi

finish
