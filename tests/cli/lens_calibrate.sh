#!/usr/bin/env bash
# setlight lens-calibrate end to end: usage errors, photos without a board,
# photos of different sizes, a missing photo (exit code, one line naming the
# file, no profile left), and the real Sigma 8mm chessboard photos (when the
# shared data is there) solved to a profile stitch can read.
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" latlong "$T/flat1.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/flat2.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/flat3.exr" 64 32 || bad "fixture"
"$MAKE_FIXTURE" latlong "$T/wide.exr" 96 48 || bad "fixture"
mkdir -p "$T/o"
P="$T/o/lens.json"
CAL=("$SETLIGHT" lens-calibrate --board 7x10 --sensor-mm 24,24 --focal-mm 8)

expect 0 "$SETLIGHT" lens-calibrate --help; out_has "usage: setlight lens-calibrate"; out_has "--radial-terms"
expect 0 "$SETLIGHT" --help; out_has "lens-calibrate"

# --- usage errors (exit 2)
expect 2 "$SETLIGHT" lens-calibrate --sensor-mm 24 -o "$P" "$T/flat1.exr"; err_has "--board"
expect 2 "$SETLIGHT" lens-calibrate --board 7x10 -o "$P" "$T/flat1.exr"; err_has "--sensor-mm"
expect 2 "$SETLIGHT" lens-calibrate --board 7 --sensor-mm 24 -o "$P" "$T/flat1.exr"; err_has "COLSxROWS"
expect 2 "${CAL[@]}" --projection fisheye -o "$P" "$T/flat1.exr"; err_has "unknown projection 'fisheye'"
expect 2 "${CAL[@]}" --radial-terms 4 -o "$P" "$T/flat1.exr"; err_has "--radial-terms"
expect 2 "${CAL[@]}" "$T/flat1.exr"; err_has "-o PROFILE.json"
absent "$P"

# --- bad input (exit 3, one line naming the file, nothing written)
expect 3 "${CAL[@]}" -o "$P" "$T/flat1.exr" "$T/flat2.exr" "$T/flat3.exr"
err_has "setlight lens-calibrate: $T/flat1.exr: only 0 of 3 photos show a 7x10 chessboard"; err_one_line
absent "$P"; no_temp "$T/o"
expect 3 "${CAL[@]}" -o "$P" "$T/flat1.exr" "$T/wide.exr"
err_has "$T/wide.exr: 96x48, but $T/flat1.exr is 64x32"; err_one_line; absent "$P"
expect 3 "${CAL[@]}" -o "$P" "$T/flat1.exr" "$T/missing.jpg"
err_has "$T/missing.jpg"; err_one_line; absent "$P"
expect 3 "$SETLIGHT" lens-calibrate --board 7x10 --sensor-mm 24 -o "$P" "$T/flat1.exr"
err_has "$T/flat1.exr: no focal length in EXIF"; err_one_line; absent "$P"

# --- the real Sigma 8mm on a Canon 6D Mark II (1600 px square = the frame's 24 mm height)
D="${SETLIGHT_SHARED_DATA:-/nonexistent}/fisheye/sigma8mm_canon6d"
if [ -f "$D/IMG_2900.JPG" ]; then
  expect 0 "$SETLIGHT" lens-calibrate --json --board 7x10 --sensor-mm 24,24 -o "$P" \
    "$D/IMG_2843.JPG" "$D/IMG_2900.JPG" "$D/IMG_2922.JPG" "$D/IMG_2938.JPG" "$D/IMG_2944.JPG"
  json_ok "$T/out"
  # EXIF gives the nominal 8 mm; the solve lands within 3% of it and puts
  # 90 deg off-axis on the photos' image circle (745 px).
  json_eval "$T/out" 'd["nominal"]["focal_mm"] == 8 and abs(d["solved"]["focal_mm"] / 8 - 1) < 0.03'
  json_eval "$T/out" 'd["rms_px"] < 1 and d["photos_used"] == 5 and abs(d["solved"]["circle_radius_px"] - 745) < 8'
  json_eval "$T/out" 'd["camera"] == "Canon EOS 6D Mark II" and all(p["found"] for p in d["photos"])'
  present "$P"; no_temp "$T/o"
  json_eval "$P" 'd["format"] == "setlight-lens" and d["source"] == "chessboard" and d["images"] == 5 and d["projection"] == "equisolid"'
  # A photo without the board is reported and left out.
  python3 -c 'import array,sys; open(sys.argv[1],"wb").write(b"PF\n1600 1600\n-1.0\n" + array.array("f",[0.5]).tobytes()*(1600*1600*3))' "$T/grey.pfm"
  expect 0 "$SETLIGHT" lens-calibrate --board 7x10 --sensor-mm 24 -o "$T/o/text.json" \
    "$D/IMG_2843.JPG" "$D/IMG_2900.JPG" "$T/grey.pfm" "$D/IMG_2922.JPG"
  out_has "$T/grey.pfm: left out: no 7x10 chessboard (inner corners) found"
  out_has "from 3 of 4 photos"; present "$T/o/text.json"
else
  skip "Sigma 8mm photos (no shared data)"
fi
finish
