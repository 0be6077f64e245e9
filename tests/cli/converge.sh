#!/bin/bash
# setlight converge end to end: table and SVG written; bad input leaves nothing.
source "$(dirname "$0")/lib.bash"
S="$SETLIGHT"
fail=0
sky_hdr "$T/env.hdr" 136
"$S" converge --env "$T/env.hdr" --scene grey --width 8 --spp 16 --reference-spp 64 --pixel-centers \
    --svg "$T/plot.svg" --table "$T/table.md" --json > "$T/out.json"
rc=$?
[ $rc -eq 0 ] || { echo "FAIL converge exit $rc"; fail=1; }
grep -q "<polyline" "$T/plot.svg" || { echo "FAIL no curves in the SVG"; fail=1; }
for s in uniform cosine bsdf light mis mis+sobol closed-form; do
    grep -q "| $s |" "$T/table.md" || { echo "FAIL table lacks $s"; fail=1; }
    grep -q "\"strategy\": \"$s\"" "$T/out.json" || { echo "FAIL json lacks $s"; fail=1; }
done
python3 -c "import json,sys; json.load(open(sys.argv[1]))" "$T/out.json" || { echo "FAIL --json is not JSON"; fail=1; }
"$S" converge --env "$T/nothing.exr" --svg "$T/bad.svg" 2> "$T/err.txt"
rc=$?
[ $rc -eq 3 ] || { echo "FAIL missing env: exit $rc"; fail=1; }
[ -e "$T/bad.svg" ] && { echo "FAIL output left behind"; fail=1; }
grep -q "nothing.exr" "$T/err.txt" || { echo "FAIL message lacks the file"; fail=1; }
"$S" converge --env "$T/env.hdr" 2> /dev/null
[ $? -eq 2 ] || { echo "FAIL no output option: not a usage error"; fail=1; }
[ $fail -eq 0 ] && echo "ok   converge"
exit $fail
