#!/usr/bin/env python3
"""Runs every shell command block of README.md, CONTRIBUTING.md and docs/*.md as written.

    python3 scripts/doc-commands.py [--list] [--bin PATH] [FILE.md ...]

A shell block is a fenced block tagged ``sh``, ``bash`` or ``shell``. Each one runs with
``bash -euo pipefail`` in its own fresh copy of the repository's tracked files (what a
clean clone holds, in their working-tree state), with ``stepdamp`` on the PATH (the
release binary, target/release/stepdamp unless --bin says otherwise) and the copy's
``target`` a link to this checkout's, so a ``cargo`` line reuses the build instead of
starting a cold one. A block must therefore create its own inputs.

A ``console`` block is a transcript: each line starting with ``$ `` is a command (a line
ending in a backslash continues it), the lines after it are what it prints. The commands
run in order in one fresh copy, stdout and stderr together, and every line shown must
appear in the command's output in the same order (lines may be left out, none changed):
a figure quoted in a transcript cannot go stale.

A block that is not meant to run carries a visible marker on the line right before its
opening fence, naming the reason::

    <!-- not-run: needs the arm-none-eabi cross toolchain -->

The script lists every skipped block with its reason, and every block it ran with its
time; it exits non-zero if any block fails (its output is shown) or if a marker names no
reason. Blocks tagged otherwise (python, c, toml, text) are not shell and are not run.

Before running anything it checks the links: every relative link of those files must name a
file that exists and, with ``#anchor``, a heading it has; so must every ``docs/….md#anchor``
that the code (crates, python, fuzz, firmware, examples, scripts) cites, and the code cites no
section numbers of a design note nor issue numbers, which users cannot read. A list of the run
log's columns after the name ``LOG_COLUMNS`` must equal that constant, and the instructions
per step in docs/embedded.md the counts in firmware/qemu-m4/instructions.txt.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SHELL_TAGS = {"sh", "bash", "shell"}
CONSOLE_TAGS = {"console"}
FENCE = re.compile(r"^(\s*)```\s*([A-Za-z0-9_+-]*)\s*$")
MARKER = re.compile(r"^\s*<!--\s*not-run:(.*?)-->\s*$")
TIMEOUT_S = 600


def blocks(path):
    """Yields (line number, tag, text, skip reason or None) for each fenced block."""
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, tag = len(m.group(1)), m.group(2).lower()
        start = i
        body = []
        i += 1
        while i < len(lines) and not re.match(r"^\s*```\s*$", lines[i]):
            line = lines[i]
            body.append(line[indent:] if line[:indent].strip() == "" else line)
            i += 1
        i += 1
        prev = start - 1
        while prev >= 0 and lines[prev].strip() == "":
            prev -= 1
        reason = None
        if prev >= 0:
            mk = MARKER.match(lines[prev])
            if mk:
                reason = mk.group(1).strip()
                if not reason:
                    raise SystemExit(f"{path}:{prev + 1}: a not-run marker must say why")
        yield start + 1, tag, "\n".join(body) + "\n", reason


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    out, fenced = set(), False
    for line in path.read_text(encoding="utf-8").splitlines():
        if re.match(r"^\s*```", line):
            fenced = not fenced
        elif not fenced and (m := re.match(r"^#{1,6}\s+(.*)$", line)):
            out.add(slug(m.group(1)))
    return out


def check_links(root, files):
    """Relative links of the markdown files, and `docs/*.md#anchor` citations in the code,
    must name a file that exists and a heading it has. Returns the broken ones."""
    broken = []
    link = re.compile(r"\]\(([^)\s]+)\)")
    for f in files:
        for n, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            for target in link.findall(line):
                if re.match(r"^[a-z]+:", target):
                    continue
                name, _, frag = target.partition("#")
                dest = (f.parent / name).resolve() if name else f
                if not dest.exists():
                    broken.append(f"{f.relative_to(root)}:{n}: {target}: no such file")
                elif frag and dest.suffix == ".md" and frag not in anchors(dest):
                    broken.append(f"{f.relative_to(root)}:{n}: {target}: no such heading")
    cited = re.compile(r"(docs/[\w./-]+\.md)#([\w-]+)")
    # Citations a user cannot follow: sections of a design note outside the repository, and
    # issue numbers of a tracker no one outside can read. Code cites docs/….md#heading.
    private = re.compile(r"design\.md\s*§|(?<![\w/])§\s*\d|\b[Ii]ssues?\s+#?\d+")
    code = subprocess.run(["git", "ls-files", "-z", "crates", "python", "fuzz", "firmware", "examples", "scripts"],
                          cwd=root, check=True, capture_output=True).stdout.decode().split("\0")
    for name in filter(None, code):
        src = root / name
        if src.suffix not in {".rs", ".py", ".pyi", ".sh", ".c", ".h", ".toml"} or not src.exists():
            continue
        for n, line in enumerate(src.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if private.search(line):
                broken.append(f"{name}:{n}: cites {private.search(line).group(0)!r}: cite docs/….md#heading")
            for doc, frag in cited.findall(line):
                dest = root / doc
                if not dest.exists():
                    broken.append(f"{name}:{n}: {doc}#{frag}: no such file")
                elif frag not in anchors(dest):
                    broken.append(f"{name}:{n}: {doc}#{frag}: no such heading")
    return broken


def check_log_columns(root, files):
    """A doc that lists the run log's columns after naming `LOG_COLUMNS` must list exactly the
    columns of stepdamp_profile::runlog::LOG_COLUMNS, in order. Returns the mismatches."""
    src = (root / "crates/stepdamp-profile/src/runlog.rs").read_text(encoding="utf-8")
    m = re.search(r"LOG_COLUMNS: \[&str; \d+\] = \[(.*?)\];", src, re.S)
    if not m:
        return ["crates/stepdamp-profile/src/runlog.rs: LOG_COLUMNS not found"]
    want = re.findall(r'"(\w+)"', m.group(1))
    bad = []
    for f in files:
        text = " ".join(f.read_text(encoding="utf-8").split())
        for listed in re.findall(r"LOG_COLUMNS`:\s*`([^`]*)`", text):
            got = [c.strip() for c in listed.split(",")]
            if got != want:
                bad.append(f"{f.relative_to(root)}: run-log columns {got} != LOG_COLUMNS {want}")
    return bad


# Rows of docs/embedded.md's table and the keys of firmware/qemu-m4/instructions.txt they show
# (a `_real` key's budget is its mode's, in firmware/qemu-m4/budget.txt).
INSTRUCTION_ROWS = {
    "open loop, patent law": "open_loop",
    "servo": "servo",
    "open loop, estimated angle": "estimated_angle",
    "open loop, patent law, with current parts": "open_loop_real",
    "servo, with current parts": "servo_real",
    "open loop, estimated angle, with current parts": "estimated_angle_real",
}


def key_values(path):
    """The `key=value` lines of path (not comments), as a dict of stripped strings."""
    return {
        k.strip(): v.strip()
        for k, v in (line.split("=", 1) for line in path.read_text().splitlines() if "=" in line and not line.startswith("#"))
    }


def check_instruction_counts(root):
    """docs/embedded.md's instructions per step (median, budget, largest step) must be what
    CI's budget check compares against (firmware/qemu-m4/instructions.txt and budget.txt).
    Returns the mismatches."""
    doc, counts = root / "docs/embedded.md", root / "firmware/qemu-m4/instructions.txt"
    budgets = root / "firmware/qemu-m4/budget.txt"
    if not doc.exists() or not counts.exists() or not budgets.exists():
        return []
    want, budget = key_values(counts), key_values(budgets)
    largest = dict(re.findall(r"^# (\w+): min \d+, max (\d+)$", counts.read_text(), re.M))
    bad, seen = [], set()
    for line in doc.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 4 and cells[0] in INSTRUCTION_ROWS:
            key = INSTRUCTION_ROWS[cells[0]]
            seen.add(key)
            mode = key.removesuffix("_real")
            for what, shown, source, expected in [
                ("instructions", cells[1], counts, want.get(key)),
                ("budget", cells[2].removeprefix("≤").strip(), budgets, budget.get(mode)),
                ("largest step", cells[3], counts, largest.get(key)),
            ]:
                if shown.replace(",", "") != (expected or ""):
                    bad.append(f"docs/embedded.md: {cells[0]}: {what} {shown}, {source.relative_to(root)} says {expected}")
    for row, key in INSTRUCTION_ROWS.items():
        if key not in seen:
            bad.append(f"docs/embedded.md: no table row '{row}' for {key}")
    return bad


def copy_tracked(root, dest):
    files = subprocess.run(["git", "ls-files", "-z"], cwd=root, check=True, capture_output=True).stdout
    for name in files.decode().split("\0"):
        if not name:
            continue
        src = root / name
        if not src.exists():  # deleted in the working tree
            continue
        target = dest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if src.is_symlink():
            os.symlink(os.readlink(src), target)
        else:
            shutil.copy2(src, target)


def run(script, cwd, env):
    """Runs a script with bash; returns (status, stdout and stderr)."""
    try:
        r = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", script],
            cwd=cwd, env=env, stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=TIMEOUT_S,
        )
        return r.returncode, r.stdout
    except subprocess.TimeoutExpired as e:
        return "timeout", f"(no end after {TIMEOUT_S} s)\n{e.stdout or ''}"


def transcript(text):
    """The (command, expected lines) pairs of a console block."""
    pairs, lines = [], text.splitlines()
    i = 0
    while i < len(lines):
        if not lines[i].startswith("$ "):
            raise ValueError(f"line {i + 1} of the block is output before any `$ ` command")
        cmd = lines[i][2:]
        while cmd.endswith("\\") and i + 1 < len(lines):
            i += 1
            cmd = cmd + "\n" + lines[i]
        i += 1
        expected = []
        while i < len(lines) and not lines[i].startswith("$ "):
            expected.append(lines[i].rstrip())
            i += 1
        pairs.append((cmd, expected))
    return pairs


def run_transcript(text, cwd, env):
    """Runs a console block's commands; fails where a shown line is not printed, in order."""
    try:
        pairs = transcript(text)
    except ValueError as e:
        return "malformed", str(e)
    log = []
    for cmd, expected in pairs:
        rc, out = run(cmd, cwd, env)
        log.append(f"$ {cmd}\n{out}")
        if rc != 0:
            return rc, "".join(log)
        got = [line.rstrip() for line in out.splitlines()]
        k = 0
        for want in expected:
            while k < len(got) and got[k] != want:
                k += 1
            if k == len(got):
                return "differs", "".join(log) + f"--- this line, shown in the doc, was not printed (in order):\n{want}\n"
            k += 1
    return 0, "".join(log)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="*", help="markdown files (default: README.md, CONTRIBUTING.md, docs/*.md)")
    ap.add_argument("--list", action="store_true", help="list the blocks and markers, run nothing")
    ap.add_argument("--bin", help="the stepdamp binary (default target/release/stepdamp)")
    args = ap.parse_args()

    root = Path(__file__).resolve().parent.parent
    if args.files:
        files = [Path(f).resolve() for f in args.files]
    else:
        files = [root / "README.md", root / "CONTRIBUTING.md"] + sorted((root / "docs").glob("*.md"))
        files = [f for f in files if f.exists()]
    binary = Path(args.bin).resolve() if args.bin else root / "target" / "release" / "stepdamp"
    if not args.list and not binary.is_file():
        raise SystemExit(f"{binary}: no such binary (cargo build --release -p stepdamp first)")

    todo, skipped = [], []
    for f in files:
        for line, tag, text, reason in blocks(f):
            if tag not in SHELL_TAGS | CONSOLE_TAGS:
                continue
            where = f"{f.relative_to(root)}:{line}"
            (skipped if reason else todo).append((where, tag, text, reason))

    broken = check_links(root, files) + check_log_columns(root, files) + check_instruction_counts(root)
    for b in broken:
        print(f"docs check: {b}")
    print(f"{len(todo)} shell blocks to run, {len(skipped)} marked not-run:")
    for where, _, _, reason in skipped:
        print(f"  skipped {where}: {reason}")
    if args.list:
        for where, _, text, _ in todo:
            print(f"\n--- {where}\n{text}", end="")
        return 0

    failed = []
    with tempfile.TemporaryDirectory(prefix="doc-commands-") as tmp:
        tmp = Path(tmp)
        bindir = tmp / "bin"
        bindir.mkdir()
        os.symlink(binary, bindir / "stepdamp")
        env = dict(os.environ)
        env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
        env.pop("CARGO_TARGET_DIR", None)
        env["CARGO_TERM_COLOR"] = "never"
        for n, (where, tag, text, _) in enumerate(todo):
            work = tmp / f"block-{n}"
            copy_tracked(root, work)
            os.symlink(root / "target", work / "target")
            t0 = time.monotonic()
            if tag in CONSOLE_TAGS:
                rc, output = run_transcript(text, work, env)
            else:
                rc, output = run(text, work, env)
            dt = time.monotonic() - t0
            status = "ok" if rc == 0 else f"FAILED ({rc})"
            print(f"  {status:>12} {dt:6.1f} s  {where}", flush=True)
            if rc != 0:
                failed.append(where)
                tail = "\n".join(str(output).splitlines()[-30:])
                print(f"--- block\n{text}--- output (last 30 lines)\n{tail}\n---", flush=True)
            shutil.rmtree(work, ignore_errors=True)
    if broken:
        failed.append(f"{len(broken)} broken links or lists")
    if failed:
        print("doc commands FAILED: " + ", ".join(failed), file=sys.stderr)
        return 1
    print(f"doc commands: {len(todo)} blocks ran, {len(skipped)} skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
