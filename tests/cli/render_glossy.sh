#!/bin/bash
# setlight render of a rough glossy ball: the glossy closed form is used and
# reported per object (--json, --stats, the log); --closed-form off samples.
source "$(dirname "$0")/lib.bash"
S="$SETLIGHT"
sky_hdr "$T/env.hdr" 140
expect 0 "$S" render --env "$T/env.hdr" --material conductor:0.9,0.7,0.5:0.3 --width 12 --pixel-centers \
    --spp 2 --json --stats "$T/s.json" -o "$T/metal.exr"
cp "$T/out" "$T/out.json"
json_eval "$T/out.json" 'd["closed_form"]["used"] and d["closed_form"]["glossy_pixels"] > 0 and d["closed_form"]["glossy_max_rel_error"] > 0'
json_eval "$T/s.json" 'd["closed_form"]["per_object"][0]["material"] == "conductor" and d["closed_form"]["per_object"][0]["bound"] == "estimate"'
json_eval "$T/s.json" 'd["closed_form"]["per_object"][0]["exact_pixels"] == d["closed_form"]["exact_pixels"] > 0'
present "$T/metal.exr"
expect 0 "$S" render --env "$T/env.hdr" --material plastic:0.5,0.5,0.5:0.4 --width 12 --spp 2 -o "$T/plastic.exr"
err_has 'closed form, object 0 (plastic): '
err_has ', 0 control variate, 0 of them interpolated; error estimate '
expect 0 "$S" render --env "$T/env.hdr" --material conductor:0.9,0.7,0.5:0.3 --width 12 --spp 2 \
    --closed-form off --stats "$T/off.json" -o "$T/off.exr"
json_eval "$T/off.json" 'not d["closed_form"]["used"] and d["closed_form"]["reason"] == "off" and d["closed_form"]["per_object"] == []'
expect 0 "$S" render --env "$T/env.hdr" --material conductor:0.9,0.7,0.5:0 --width 12 --spp 2 \
    --stats "$T/chrome.json" -o "$T/chrome.exr"
json_eval "$T/chrome.json" 'd["closed_form"]["reason"] == "no Lambert or rough glossy object"'
finish
