#!/usr/bin/env bash
# setlight rig, then setlight render --rig on the rig.json it wrote (v1).
. "$(dirname "$0")/lib.bash"

"$MAKE_FIXTURE" sun "$T/sun.exr" 64 32 || bad "fixture"
if "$SETLIGHT" rig "$T/sun.exr" -o "$T/rig.usda" --json "$T/rig.json" --residual "$T/res.exr" \
    > "$T/summary.json"; then ok; else bad "setlight rig failed"; fi
if "$SETLIGHT" render --rig "$T/rig.json" --scene grey --width 8 --spp 4 -o "$T/out.exr" --quiet; then
    ok
else
    bad "render --rig rig.json failed"
fi
if [ -s "$T/out.exr" ]; then ok; else bad "no render written"; fi

finish
