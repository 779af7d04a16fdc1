#!/usr/bin/env python3
"""Call graph of the firmware ELF from `arm-none-eabi-objdump -d -C` output.

Used by check-symbols.sh (forbidden callees reachable from the step wrappers) and by
count-instructions.sh (the address ranges that belong to one controller step).

    callgraph.py reachable OBJDUMP_TXT ROOT...    # one line per function: name start end
    callgraph.py check OBJDUMP_TXT ROOT...        # exit 1 if a forbidden callee is reachable

A call is any branch (bl, blx, b, b.w, bcc, cbz, ...) whose target lies in another
function; indirect branches (blx rN, bx rN other than bx lr, ldr pc, mov pc) inside a
reachable function are reported, since the walk cannot follow them.
"""
import re
import sys

FUNC = re.compile(r"^([0-9a-f]+) <(.+)>:$")
INSN = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)(?:\s+(.*))?$")
TARGET = re.compile(r"\b([0-9a-f]+) <([^>]+)>")
# Software double precision, 64-bit division, min/max library calls, panics.
FORBIDDEN = re.compile(
    r"^(__aeabi_d\w*|__(add|sub|mul|div)df3|__aeabi_uldivmod|__aeabi_ldivmod|__udivdi3|__divdi3"
    r"|__(u)?moddi3|fminf?|fmaxf?|f(min|max)imum\w*|.*panic.*|.*unwrap_failed.*|.*expect_failed.*"
    r"|.*slice_(start_|end_)?index.*fail.*|.*array_index.*fail.*|.*bounds_check.*|.*slice_.*_fail.*)$"
)


def parse(path):
    funcs = {}  # name -> [start, end, [(mnemonic, operands)]]
    order = []
    cur = None
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            line = line.rstrip("\n")
            m = FUNC.match(line)
            if m:
                cur = m.group(2)
                start = int(m.group(1), 16)
                funcs[cur] = [start, start, []]
                order.append(cur)
                continue
            if cur is None:
                continue
            m = INSN.match(line)
            if m:
                addr = int(m.group(1), 16)
                funcs[cur][1] = max(funcs[cur][1], addr)
                funcs[cur][2].append((addr, m.group(2), m.group(3) or ""))
    return funcs


def callees(funcs, name):
    out, indirect = set(), []
    for addr, mnem, ops in funcs[name][2]:
        base = mnem.split(".")[0]
        is_branch = base.startswith("b") and base not in ("bic", "bics", "bfi", "bfc", "bkpt")
        if is_branch or base in ("cbz", "cbnz"):
            t = TARGET.search(ops)
            if t:
                target = t.group(2).split("+")[0]
                if target != name and target in funcs:
                    out.add(target)
            elif base in ("blx", "bx") and ops.strip() != "lr":
                indirect.append(f"{addr:08x}: {mnem} {ops}")
        elif ("pc" in ops.split(",")[0]) and base in ("ldr", "mov", "pop", "ldm") and base != "pop":
            indirect.append(f"{addr:08x}: {mnem} {ops}")
    return out, indirect


def reachable(funcs, roots):
    seen, stack, indirect, parent = set(), list(roots), {}, {}
    while stack:
        n = stack.pop()
        if n in seen:
            continue
        seen.add(n)
        outs, ind = callees(funcs, n)
        if ind:
            indirect[n] = ind
        for c in outs:
            if c not in seen:
                parent.setdefault(c, n)
                stack.append(c)
    return seen, indirect, parent


def main():
    cmd, path, roots = sys.argv[1], sys.argv[2], sys.argv[3:]
    funcs = parse(path)
    missing = [r for r in roots if r not in funcs]
    if missing:
        sys.exit(f"callgraph: no function named {missing} in the disassembly")
    seen, indirect, parent = reachable(funcs, roots)
    if cmd == "reachable":
        for n in sorted(seen, key=lambda n: funcs[n][0]):
            # end: address of the last instruction (inclusive)
            print(f"{funcs[n][0]:x} {funcs[n][1]:x} {n}")
        return
    bad = sorted(n for n in seen if FORBIDDEN.match(n))
    for n in sorted(seen, key=lambda n: funcs[n][0]):
        print(f"  reachable: {n}")
    status = 0
    for n in bad:
        chain, c = [n], n
        while c in parent:
            c = parent[c]
            chain.append(c)
        print(f"FORBIDDEN reachable: {n}  (via {' <- '.join(chain[1:])})")
        status = 1
    for n, ind in indirect.items():
        for i in ind:
            print(f"INDIRECT branch the walk cannot follow in {n}: {i}")
        status = 1
    sys.exit(status)


if __name__ == "__main__":
    main()
