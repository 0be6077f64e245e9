#!/usr/bin/env bash
# Resource caps (issue 22, defect 4): a header that claims more pixels than
# its file can hold, an image over the memory budget (--max-memory-mb,
# SETLIGHT_MAX_MEMORY_MB), a display window of padding over the budget, and
# rig / scene files with more lights or objects than the documented limits:
# each refused before the allocation, exit 3, one line naming the file, no
# output or temp left.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" code128 "$T/small.jpg" 64 32 || bad "fixture"
"$MAKE_FIXTURE" code128 "$T/small.tif" 64 32 || bad "fixture"
"$MAKE_FIXTURE" code128 "$T/small.png" 64 32 || bad "fixture"
"$MAKE_FIXTURE" code128 "$T/mid.jpg" 512 256 || bad "fixture"
"$MAKE_FIXTURE" code128 "$T/mid.png" 512 256 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/env.exr" 64 32 || bad "fixture"

# patch KIND SRC DST W H: the header's size rewritten, the pixels kept.
patch() {
  python3 - "$@" <<'PY'
import struct, sys, zlib
kind, src, dst, w, h = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
b = bytearray(open(src, 'rb').read())
if kind == 'jpeg':  # the frame header (SOF0..SOF2): precision, height, width
    i = next(i for i in range(2, len(b) - 1) if b[i] == 0xff and b[i + 1] in (0xc0, 0xc1, 0xc2))
    struct.pack_into('>HH', b, i + 5, h, w)
elif kind == 'png':  # IHDR, with its CRC made right again
    struct.pack_into('>II', b, 16, w, h)
    struct.pack_into('>I', b, 29, zlib.crc32(bytes(b[12:29])))
elif kind == 'tiff':  # ImageWidth (256) and ImageLength (257) in the first IFD
    e = '<' if b[:2] == b'II' else '>'
    ifd = struct.unpack_from(e + 'I', b, 4)[0]
    for k in range(struct.unpack_from(e + 'H', b, ifd)[0]):
        o = ifd + 2 + 12 * k
        tag, typ = struct.unpack_from(e + 'HH', b, o)
        if tag in (256, 257):
            struct.pack_into(e + ('H' if typ == 3 else 'I'), b, o + 8, w if tag == 256 else h)
elif kind == 'exr':  # the display window; the data window stays
    key = b'displayWindow\x00box2i\x00'
    struct.pack_into('<iiii', b, b.index(key) + len(key) + 4, 0, 0, w - 1, h - 1)
open(dst, 'wb').write(b)
PY
}
patch jpeg "$T/small.jpg" "$T/huge.jpg" 40000 20000
patch tiff "$T/small.tif" "$T/huge.tif" 40000 20000
patch png "$T/small.png" "$T/huge.png" 40000 20000
printf '#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 20000 +X 40000\n\002\002\234\100' >"$T/huge.hdr"

# --- a header claiming more than its file can hold: refused, whatever the budget
for f in huge.jpg huge.tif huge.png huge.hdr; do
  expect 3 "$SETLIGHT" info "$T/$f"; err_has "$T/$f"; err_has "40000x20000"; err_has "can hold"
  err_one_line
  expect 3 "$SETLIGHT" convert "$T/$f" "$T/out_$f.exr"; err_one_line; absent "$T/out_$f.exr"
done
expect 3 "$SETLIGHT" merge -o "$T/merged.exr" "$T/huge.jpg" "$T/small.jpg"
err_has "huge.jpg"; err_one_line; absent "$T/merged.exr"; no_temp "$T"
# the same pictures at their real size are read
expect 0 "$SETLIGHT" info "$T/small.jpg" "$T/small.tif" "$T/small.png"

# --- the memory budget: 512 x 256 RGB is 1.5 MB as float
for f in mid.jpg mid.png; do
  expect 3 "$SETLIGHT" info --max-memory-mb 1 "$T/$f"
  err_has "$T/$f: a 512x256"; err_has "memory budget of 1 MB"; err_one_line
  expect 0 "$SETLIGHT" info --max-memory-mb=2 "$T/$f"
  SETLIGHT_MAX_MEMORY_MB=1 expect 3 "$SETLIGHT" convert "$T/$f" "$T/mid_out.exr"
  err_has "memory budget of 1 MB"; err_one_line; absent "$T/mid_out.exr"
done
# the option wins over the variable
SETLIGHT_MAX_MEMORY_MB=1 expect 0 "$SETLIGHT" info --max-memory-mb 2 "$T/mid.png"
for v in 0 -5 x 1.5 ""; do
  expect 2 "$SETLIGHT" info --max-memory-mb "$v" "$T/mid.png"; err_has "--max-memory-mb"; err_one_line
done
SETLIGHT_MAX_MEMORY_MB=lots expect 2 "$SETLIGHT" info "$T/mid.png"
err_has "SETLIGHT_MAX_MEMORY_MB"; err_one_line
expect 0 "$SETLIGHT" --help; out_has "--max-memory-mb"

# --- an EXR's display window: 64 x 32 of data in 8192 x 4096 of padding.
# 384 MB as an image, 1.8 GB as a dome with its sampling tables.
patch exr "$T/env.exr" "$T/padded.exr" 8192 4096
expect 3 "$SETLIGHT" render --max-memory-mb 300 --env "$T/padded.exr" --scene grey --width 16 \
  --spp 1 -o "$T/r.exr"
err_has "padded.exr: the 8192x4096 display window (data window 64x32) needs 384 MB"; err_one_line
absent "$T/r.exr"
expect 3 "$SETLIGHT" render --max-memory-mb 1000 --env "$T/padded.exr" --scene grey --width 16 \
  --spp 1 -o "$T/r.exr"
err_has "padded.exr: a 8192x4096 dome with its sampling tables needs 1792 MB"; err_one_line
absent "$T/r.exr"; no_temp "$T"

# --- counts: a rig of 5000 lights, a scene of 5000 objects, a 20 MB rig file
python3 - "$T" <<'PY'
import json, sys
light = {"type": "distant", "direction": [0, 1, 0], "solid_angle": 0.01, "radiance": [1, 1, 1],
         "position": None, "size": None, "texture": None}
json.dump({"version": 1, "lights": [light] * 5000, "dome": {"file": None}},
          open(sys.argv[1] + "/many.json", "w"))
json.dump({"version": 1, "lights": [light] * 4096, "dome": {"file": None}},
          open(sys.argv[1] + "/most.json", "w"))
sphere = {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}
json.dump({"materials": {"m": {"type": "lambert"}}, "objects": [sphere] * 5000},
          open(sys.argv[1] + "/scene.json", "w"))
PY
expect 3 "$SETLIGHT" render --rig "$T/many.json" --scene grey --width 8 --spp 1 -o "$T/r.exr"
err_has "many.json: 5000 lights, more than a rig may hold (4096)"; err_one_line; absent "$T/r.exr"
expect 0 "$SETLIGHT" render --rig "$T/most.json" --scene grey --width 4 --spp 1 -o "$T/r4096.exr" --quiet
expect 3 "$SETLIGHT" render --env "$T/env.exr" --scene "$T/scene.json" --width 8 --spp 1 -o "$T/r.exr"
err_has "scene.json: 5000 objects"; err_has "(4096 each)"; err_one_line; absent "$T/r.exr"
printf '{"version": 1, "lights": [], "dome": {"file": null}}' >"$T/big.json"
truncate -s 20M "$T/big.json"
expect 3 "$SETLIGHT" render --rig "$T/big.json" --scene grey --width 8 --spp 1 -o "$T/r.exr"
err_has "big.json: 20 MB, larger than a rig JSON may be (16 MB)"; err_one_line; absent "$T/r.exr"
# A 423-byte PNG whose tEXt chunk claims 1.4 GB (found by fuzz_photo): refused
# from the chunk's length before libpng allocates it (it cost 5 s and 1.4 GB).
png_text="$SETLIGHT_SOURCE_DIR/tests/fuzz_regressions/photo/png_text_chunk_length.png"
expect 3 "$SETLIGHT" convert "$png_text" "$T/text_out.exr"
err_has "png_text_chunk_length.png: truncated or corrupt PNG: its tEXt chunk claims 1409286164 bytes"
err_one_line; absent "$T/text_out.exr"
# A 1.5 KB DWAA EXR whose string attribute claims 1.7 GB (found by fuzz_exr):
# OpenEXRCore's parse notes the damage; refused before OpenEXR's C++ reader
# allocates the claim (it cost 8.5 s and 1.8 GB).
dwa="$SETLIGHT_SOURCE_DIR/tests/fuzz_regressions/exr/exr_dwa_attribute_size.exr"
expect 3 "$SETLIGHT" convert "$dwa" "$T/dwa_out.exr"
err_has "exr_dwa_attribute_size.exr: truncated or corrupt EXR (Attribute 'Exif:ImageHistory'"
err_one_line; absent "$T/dwa_out.exr"
no_temp "$T"
finish
