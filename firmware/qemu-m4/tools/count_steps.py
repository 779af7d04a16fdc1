#!/usr/bin/env python3
"""Counts the instructions QEMU executed per call of the step wrapper.

    count_steps.py RANGES ROOT RETURN_SITES < qemu-exec-log

RANGES: `start end name` lines (hex, end inclusive) from `callgraph.py reachable`;
ROOT: the step wrapper's name (its start is the entry); RETURN_SITES: comma-separated
hex addresses where the caller resumes after calling it. A step is every instruction
from the entry up to (not including) the next return site. The log is QEMU's
`-d exec,nochain` with one instruction per translation block (`-singlestep` /
`one-insn-per-tb=on`), usually restricted by `-dfilter` to RANGES and the return sites:
one `Trace` line per executed instruction, PC in the second field of the brackets. A PC
outside RANGES during a step is an error (a call the graph walk missed). Prints one
count per call, in call order.
"""
import bisect
import sys


def main():
    ranges_path, root = sys.argv[1], sys.argv[2]
    returns = {int(a, 16) for a in sys.argv[3].split(",")}
    starts, ends, entry = [], [], None
    with open(ranges_path) as f:
        for line in f:
            s, e, name = line.rstrip("\n").split(" ", 2)
            starts.append(int(s, 16))
            ends.append(int(e, 16))
            if name == root:
                entry = int(s, 16)
    if entry is None:
        sys.exit(f"count_steps: {root} not in {ranges_path}")
    order = sorted(range(len(starts)), key=lambda i: starts[i])
    starts = [starts[i] for i in order]
    ends = [ends[i] for i in order]
    cache = {}

    def inside(pc):
        v = cache.get(pc)
        if v is None:
            i = bisect.bisect_right(starts, pc) - 1
            v = i >= 0 and pc <= ends[i]
            cache[pc] = v
        return v

    counting, n = False, 0
    out = sys.stdout
    for line in sys.stdin.buffer:
        if not line.startswith(b"Trace "):
            continue
        b = line.find(b"[")
        s1 = line.find(b"/", b)
        pc = int(line[s1 + 1 : line.find(b"/", s1 + 1)], 16) & ~1
        if counting:
            if pc in returns:
                out.write(f"{n}\n")
                counting = False
                continue
            if not inside(pc):
                sys.exit(f"count_steps: PC {pc:#x} outside the step's call graph during step")
            n += 1
            if pc == entry:
                sys.exit("count_steps: the step wrapper re-entered before returning")
        elif pc == entry:
            counting, n = True, 1
    if counting:
        sys.exit("count_steps: the log ended inside a step")


if __name__ == "__main__":
    main()
