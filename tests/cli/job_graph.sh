#!/bin/bash
# The job graph read back by `setlight job`, process-report and process-index
# (docs/process.md): a hand-made graph of plain commands runs and stamps; a
# graph edited into one that does not hold together (a job without a stage,
# an id leading out of OUT, an unknown dependency, a cycle, a relative path)
# is refused with one line naming the file and the job, exit 3, before
# anything is written.
. "$(dirname "$0")/lib.bash"
S="$SETLIGHT"
D="$T/day"

# graph FILE JOB...: a graph out "$D" of the given jobs (JSON objects).
graph() {
  local f=$1
  shift
  local IFS=,
  printf '{"format":"setlight-jobs","version":1,"setlight":"0.1.0","out":"%s","jobs":[%s]}\n' "$D" "$*" >"$f"
}
# job ID DEPS [OVERRIDES]: a job copying in.txt to ID.txt; OVERRIDES
# (',"key":value') replace fields.
job() {
  python3 - "$D" "$T/in.txt" "$@" <<'P'
import json, sys
d, src, id, deps = sys.argv[1:5]
j = {"id": id, "setup": "s", "stage": "merge", "argv": ["setlight", "job", "jobs.json", id],
     "command": ["/bin/cp", src, "%s/%s.txt" % (d, id)], "inputs": [src],
     "outputs": ["%s/%s.txt" % (d, id)], "deps": [x for x in deps.split(",") if x], "array": None,
     "memory_mb": 1, "cpus": 1, "log": "%s/logs/%s.log" % (d, id.replace("/", "_")), "key": None,
     "up_to_date": False}
j.update(json.loads("{%s}" % (sys.argv[5][1:] if len(sys.argv) > 5 else "")))
print(json.dumps(j))
P
}
expect 0 "$S" job --help
out_has "The graph is checked whole first"
echo first >"$T/in.txt"

# A good graph: the job runs, then is up to date.
graph "$T/good.json" "$(job s/a "")" "$(job s/b s/a)"
expect 0 "$S" job "$T/good.json" s/b
present "$D/s/b.txt"
present "$D/s/b.stamp.json"
expect 2 "$S" job "$T/good.json" s/none
err_one_line
err_has "good.json: no job 's/none'"
rm -rf "$D"

# Several jobs in one process (a grouped setup's Slurm job): in turn, each
# only after the listed jobs it depends on succeeded. A failed job's
# dependant is not run, an unrelated job is; exit 1. Then all three run.
graph "$T/many.json" "$(job s/a "" ',"command":["/bin/false"]')" "$(job s/b s/a)" "$(job s/c "")"
expect 1 "$S" job "$T/many.json" s/a s/b s/c
if grep -q '"status": "failed"' "$D/s/a.stamp.json"; then ok; else bad "s/a: no failed stamp"; fi
absent "$D/s/b.stamp.json"
present "$D/s/c.txt"
graph "$T/many.json" "$(job s/a "")" "$(job s/b s/a)" "$(job s/c "")"
expect 0 "$S" job "$T/many.json" s/a s/b s/c
present "$D/s/b.txt"
expect 1 "$S" job "$T/many.json" s/c s/none
err_one_line
err_has "many.json: no job 's/none'"
rm -rf "$D"

# An input that is no regular file (a device never ends, a FIFO blocks):
# refused before it is hashed or anything is written.
graph "$T/device.json" "$(job s/a "" ',"inputs":["/dev/zero"]')"
expect 3 timeout 20 "$S" job "$T/device.json" s/a
err_one_line
err_has "setlight job: $T/device.json: job 's/a': input /dev/zero is not a regular file"
absent "$D"

# Edited graphs: refused, one line, exit 3, nothing written under OUT.
refused() { # FILE MESSAGE: job, process-report and process-index all refuse FILE
  for cmd in "job $1 s/a" "process-report $1 s" "process-index $1"; do
    # shellcheck disable=SC2086
    expect 3 "$S" $cmd
    err_one_line
    err_has "setlight ${cmd%% *}: $1: $2"
    absent "$D"
  done
}
graph "$T/no_stage.json" "$(job s/a "" ',"stage":null')"
refused "$T/no_stage.json" "job 's/a': \"stage\" is not one of merge"
graph "$T/escape.json" "$(job ../../a "")"
refused "$T/escape.json" "job 1: \"id\" is not a relative path"
graph "$T/unknown.json" "$(job s/a s/gone)"
refused "$T/unknown.json" "job 's/a': dependency 's/gone' is not a job of the graph"
graph "$T/cycle.json" "$(job s/a s/c)" "$(job s/b s/a)" "$(job s/c s/b)"
refused "$T/cycle.json" "job 's/a': its dependencies form a cycle (s/a -> s/c -> s/b -> s/a)"
graph "$T/relative.json" "$(job s/a "" ',"log":"logs/a.log"')"
refused "$T/relative.json" "job 's/a': \"log\" is not an absolute path"
head -c 100 "$T/good.json" >"$T/cut.json"
refused "$T/cut.json" "not a job graph: line 1:"
# A graph past the size cap is refused before it is read.
python3 -c 'import sys; open(sys.argv[1], "w").write(" " * (16 << 20) + "{}")' "$T/huge.json"
refused "$T/huge.json" "16 MB, larger than a job graph may be (16 MB)"
rm -f "$T/huge.json"

finish
