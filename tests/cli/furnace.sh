#!/bin/bash
# setlight furnace: exit codes, --help, the JSON shape and its thresholds.
set -u
fail() { echo "FAIL: $*"; exit 1; }

"$SETLIGHT" furnace --help | grep -q "White furnace" || fail "--help does not describe the command"
"$SETLIGHT" furnace --samples 3 2>/dev/null; [ $? -eq 2 ] || fail "--samples 3 is not a usage error"
"$SETLIGHT" furnace --bogus 2>/dev/null; [ $? -eq 2 ] || fail "unknown option is not a usage error"
"$SETLIGHT" furnace --samples 256 | grep -q "conductor, compensated" || fail "no human table"

out=$("$SETLIGHT" furnace --json --samples 1024) || fail "furnace --json exited $?"
python3 -c '
import json, sys
d = json.loads(sys.argv[1])
cases = d["cases"]
assert len(cases) > 100, len(cases)
keys = {"bsdf", "roughness", "cos_theta", "compensated", "albedo", "expected"}
for c in cases:
    assert set(c) == keys, c
    assert isinstance(c["compensated"], bool)
    assert 0.0 <= c["roughness"] <= 1.0 and 0.0 < c["cos_theta"] <= 1.0
    assert c["expected"] == 1.0
fams = {c["bsdf"] for c in cases}
assert fams == {"lambert", "conductor", "conductor_aniso", "plastic"}, fams
for c in cases:
    if c["bsdf"] in ("conductor", "conductor_aniso", "plastic") and c["compensated"]:
        assert abs(c["albedo"] - 1.0) <= 0.01, c
    if c["bsdf"] == "lambert":
        assert abs(c["albedo"] - 1.0) <= 0.005, c
r1 = [c["albedo"] for c in cases if c["bsdf"] == "conductor" and not c["compensated"]
      and c["roughness"] == 1.0 and c["cos_theta"] == 1.0]
assert len(r1) == 1 and 0.28 < r1[0] < 0.33, r1
' "$out" || fail "JSON checks"
echo "ok"
