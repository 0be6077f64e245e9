#!/usr/bin/env python3
"""The wall time a run would take on 2 idle cores, from a scheduler trace
taken on a loaded machine (docs/stitch.md, "Speed"): between consecutive
scheduler events the run's work (its running threads x the time) is divided
by min(its runnable threads, 2), what 2 idle cores do with that many
runnable threads, and summed. The run's CPU time is what the loaded machine
gives (a little over an idle one's: caches shared). With the run's --json,
the same per phase of its `timing` (placed from the start, start-up and
exit split evenly), and how much of it had one runnable thread only.

    perf sched record -o t.data -- sh -c 'echo $$ > t.pid; exec ./build/setlight \\
        stitch --json --focal-mm 8 --sensor-mm 36,24 -o /tmp/v/out.exr /tmp/v/view*.exr' > t.json
    perf script -i t.data -F comm,tid,cpu,time,event,trace > t.txt
    bench/stitch_idle_wall.py t.txt $(cat t.pid) t.json
"""
import json
import re
import sys

EVENT = re.compile(r"^\s*(.+?)\s+(-?\d+)\s+\[(\d+)\]\s+([\d.]+):\s+(\S+):\s+(.*)$")
SWITCH = re.compile(r"prev_pid=(\d+) prev_prio=\d+ prev_state=(\S+) ==> .*next_pid=(\d+)")
WAKE = re.compile(r"pid=(\d+) prio")
FORK = re.compile(r" pid=(\d+) child_comm=.* child_pid=(\d+)")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    mine = {int(sys.argv[2])}  # the run's process and every thread it starts
    phases = []
    if len(sys.argv) > 3:
        timing = json.load(open(sys.argv[3]))["timing"]
        phases = [(k, v["wall"]) for k, v in timing.items() if k != "total" and "wall" in v]
        total = timing["total"]["wall"]
    running, runnable = set(), set()
    steps = []  # (time, work, idle-core time, work with one runnable thread)
    first = last = t_prev = None
    for line in open(sys.argv[1]):
        m = EVENT.match(line)
        if not m:
            continue
        t, name, rest = float(m.group(4)), m.group(5), m.group(6)
        if t_prev is not None and running:
            dt = t - t_prev
            n, r = len(running), max(len(runnable), len(running))
            steps.append((t, n * dt, n * dt / min(r, 2), n * dt if r == 1 else 0.0))
        t_prev = t
        if name == "sched:sched_process_fork":
            f = FORK.search(rest)
            if f and int(f.group(1)) in mine:
                mine.add(int(f.group(2)))
        elif name == "sched:sched_switch":
            s = SWITCH.search(rest)
            if not s:
                continue
            prev, state, nxt = int(s.group(1)), s.group(2), int(s.group(3))
            if prev in mine:
                running.discard(prev)
                (runnable.add if state.startswith("R") else runnable.discard)(prev)
            if nxt in mine:
                running.add(nxt)
                runnable.add(nxt)
                first = t if first is None else first
                last = t
        elif name in ("sched:sched_waking", "sched:sched_wakeup", "sched:sched_wakeup_new"):
            w = WAKE.search(rest)
            if w and int(w.group(1)) in mine:
                runnable.add(int(w.group(1)))
    if first is None:
        sys.exit("no event of process %s in %s" % (sys.argv[2], sys.argv[1]))
    work = sum(s[1] for s in steps)
    idle = sum(s[2] for s in steps)
    print("traced wall %.2f s, CPU %.2f s, on 2 idle cores about %.2f s" % (last - first, work, idle))
    if phases:
        at = first + ((last - first) - total) / 2
        for name, wall in phases:
            inside = [s for s in steps if at <= s[0] < at + wall]
            print("  %-7s %.2f s (CPU %.2f, one thread runnable %.2f)" %
                  (name, sum(s[2] for s in inside), sum(s[1] for s in inside),
                   sum(s[3] for s in inside)))
            at += wall


if __name__ == "__main__":
    main()
