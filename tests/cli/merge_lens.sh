#!/usr/bin/env bash
# merge carries the frames' lens EXIF into the merged EXR (focal length, camera,
# lens, and the sensor size of a known body); a bracket mixing lenses is refused.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" latlong "$T/base.exr" 64 32 || bad "fixture"
for t in 1 0.25 0.0625; do
  "$MAKE_FIXTURE" lens "$T/f_$t.tif" "$T/base.exr" "$t" "8mm F3.5 EX DG CIRCULAR FISHEYE" 8 || bad "fixture"
done
"$MAKE_FIXTURE" lens "$T/odd.tif" "$T/base.exr" 0.25 "15mm F2.8 EX DG DIAGONAL FISHEYE" 15 || bad "fixture"

expect 0 "$SETLIGHT" merge --response linear -o "$T/hdr.exr" "$T/f_1.tif" "$T/f_0.25.tif" "$T/f_0.0625.tif"
expect 0 "$SETLIGHT" info "$T/hdr.exr"
out_has "8mm F3.5 EX DG CIRCULAR FISHEYE, 8 mm"
out_has "Canon EOS 5D Mark II"
out_has "setlight:lens:sensor_mm 36 x 24"
out_has "setlight:lens:focal_35mm 8"

expect 3 "$SETLIGHT" merge --response linear -o "$T/mixed.exr" "$T/f_1.tif" "$T/odd.tif" "$T/f_0.0625.tif"
err_has "odd.tif: lens '15mm F2.8 EX DG DIAGONAL FISHEYE' at 15 mm"
err_has "(frames from different lenses)"
err_one_line
absent "$T/mixed.exr"
no_temp "$T"

finish
