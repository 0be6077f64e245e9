#!/usr/bin/env python3
"""Validates a setlight job graph (setlight process --emit-jobs, OUT/jobs.json):
against docs/jobs.schema.json (python3-jsonschema), then what a schema cannot
say. Exit 0 valid, 1 invalid (the first problems on stderr), 2 usage.
   check_jobs.py SCHEMA JOBS.json"""
import json
import sys

import jsonschema


def graph_problems(doc):
    """What the schema cannot check: the graph holds together."""
    out = []
    seen = {}
    jobs = doc["jobs"]
    for n, j in enumerate(jobs):
        i = j["id"]
        if i in seen:
            out.append("%s: two jobs of this id" % i)
        if j["argv"][3] != i:
            out.append("%s: argv runs job %s" % (i, j["argv"][3]))
        if j["stage"] != "index":
            if not i.startswith(j["setup"] + "/" + j["stage"]):
                out.append("%s: id does not match setup %s and stage %s" % (i, j["setup"], j["stage"]))
        for d in j["deps"]:
            if d not in seen:
                out.append("%s: depends on %s, %s" % (i, d, "listed after it (or a cycle)"
                                                      if any(x["id"] == d for x in jobs) else "not in the graph"))
        seen[i] = j
    arrays = {}
    for j in jobs:
        if j["array"] is not None:
            arrays.setdefault(j["array"], []).append(j)
    for a, members in arrays.items():
        if len({tuple(sorted(m["deps"])) for m in members}) > 1:
            out.append("array %s: its jobs wait for different jobs" % a)
    index = [j for j in jobs if j["stage"] == "index"]
    if len(index) != 1 or jobs[-1]["stage"] != "index":
        out.append("the graph must end with exactly one index job")
    argv2 = {j["argv"][2] for j in jobs}
    if len(argv2) > 1:
        out.append("jobs name different graph files: %s" % sorted(argv2)[:2])
    return out


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    schema = json.load(open(sys.argv[1]))
    doc = json.load(open(sys.argv[2]))
    validator = jsonschema.Draft202012Validator(schema)
    problems = ["%s: %s" % ("/".join(map(str, e.absolute_path)), e.message)
                for e in validator.iter_errors(doc)]
    if not problems:
        problems = graph_problems(doc)
    for p in problems[:5]:
        print("%s: %s" % (sys.argv[2], p), file=sys.stderr)
    return 1 if problems else 0


sys.exit(main())
