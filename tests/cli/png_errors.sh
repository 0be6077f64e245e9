#!/usr/bin/env bash
# A corrupt or cut PNG through info, convert and merge: exit 3 and one line
# naming the file, from setlight (never libpng's own "libpng error:" line,
# which OpenImageIO's PNG reader lets libpng print for the interlaced and
# EXIF-carrying PNGs setlight hands to it), and no output left behind.
. "$(dirname "$0")/lib.bash"

# PNGs written here: plain and Adam7-interlaced RGB, one with an eXIf chunk,
# then cut, with a wrong IDAT CRC, or with a bad filter byte.
python3 - "$T" <<'EOF'
import struct, sys, zlib
out = sys.argv[1]
w, h = 48, 24
px = [[((x * 5) % 256, (y * 9) % 256, 128) for x in range(w)] for y in range(h)]

def chunk(t, d):
    return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)

def rows(pix, filt=0):
    return b''.join(bytes([filt]) + bytes(v for p in r for v in p) for r in pix)

def png(data, interlace=0, extra=b''):
    ihdr = struct.pack('>IIBBBBB', w, h, 8, 2, 0, 0, interlace)
    return (b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', ihdr) + extra +
            chunk(b'IDAT', zlib.compress(data)) + chunk(b'IEND', b''))

def adam7(filt=0):
    passes = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]
    data = b''
    for x0, y0, dx, dy in passes:
        sub = [[px[y][x] for x in range(x0, w, dx)] for y in range(y0, h, dy)]
        if sub and sub[0]:
            data += rows(sub, filt)
    return data

exif = chunk(b'eXIf', b'MM\x00\x2a\x00\x00\x00\x08\x00\x00')
files = {
    'plain.png': png(rows(px)),
    'interlaced.png': png(adam7(), 1),
    'exif.png': png(rows(px), 0, exif),
    'interlaced_badfilter.png': png(adam7(7), 1),
    'exif_badfilter.png': png(rows(px, 9), 0, exif),
}
for name in ('plain', 'interlaced', 'exif'):
    files[name + '_cut.png'] = files[name + '.png'][:120]
    d = bytearray(files[name + '.png'])
    i = d.find(b'IDAT')
    n = struct.unpack('>I', d[i - 4:i])[0]
    d[i + 4 + n] ^= 0xff
    files[name + '_crc.png'] = bytes(d)
for k, v in files.items():
    open(out + '/' + k, 'wb').write(v)
EOF

# --- the good ones read (the interlaced and EXIF ones through OpenImageIO)
for f in plain interlaced exif; do
  expect 0 "$SETLIGHT" info --json "$T/$f.png"
  json_eval "$T/out" 'd["files"][0]["width"] == 48 and d["files"][0]["height"] == 24'
done

# --- bad ones: one line from setlight naming the file, exit 3, nothing written
for f in plain_cut plain_crc interlaced_cut interlaced_crc interlaced_badfilter exif_cut exif_crc \
  exif_badfilter; do
  p="$T/$f.png"
  expect 3 "$SETLIGHT" info "$p"; err_has "setlight info: $p: "; err_one_line
  expect 3 "$SETLIGHT" convert "$p" "$T/$f.exr"; err_has "setlight convert: $p: "; err_one_line
  absent "$T/$f.exr"
  expect 3 "$SETLIGHT" merge --times 1/30,1/120 -o "$T/${f}_m.exr" "$T/plain.png" "$p"
  err_has "setlight merge: $p: "; err_one_line
  absent "$T/${f}_m.exr"
  if grep -q 'libpng' "$T/err"; then bad "$f: libpng's own message on stderr"; else ok; fi
done
no_temp "$T"

finish
