#!/usr/bin/env python3
"""Runs every shell command block of README.md, CONTRIBUTING.md and docs/*.md as written.

    python3 scripts/doc-commands.py [--list] [--bin PATH] [FILE.md ...]

A shell block is a fenced block tagged ``sh``, ``bash`` or ``shell``. Each one runs with
``bash -euo pipefail`` in its own fresh copy of the repository's tracked files (what a
clean clone holds, in their working-tree state), with ``stepdamp`` on the PATH (the
release binary, target/release/stepdamp unless --bin says otherwise) and CARGO_TARGET_DIR
set to this checkout's target/, so a ``cargo`` line reuses the build instead of starting
a cold one. A block must therefore create its own inputs.

A block that is not meant to run carries a visible marker on the line right before its
opening fence, naming the reason::

    <!-- not-run: needs the arm-none-eabi cross toolchain -->

The script lists every skipped block with its reason, and every block it ran with its
time; it exits non-zero if any block fails (its output is shown) or if a marker names no
reason. Blocks tagged otherwise (python, c, toml, text) are not shell and are not run.
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
            if tag not in SHELL_TAGS:
                continue
            where = f"{f.relative_to(root)}:{line}"
            (skipped if reason else todo).append((where, text, reason))

    print(f"{len(todo)} shell blocks to run, {len(skipped)} marked not-run:")
    for where, _, reason in skipped:
        print(f"  skipped {where}: {reason}")
    if args.list:
        for where, text, _ in todo:
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
        env["CARGO_TARGET_DIR"] = str(root / "target")
        env["CARGO_TERM_COLOR"] = "never"
        for n, (where, text, _) in enumerate(todo):
            work = tmp / f"block-{n}"
            copy_tracked(root, work)
            t0 = time.monotonic()
            try:
                r = subprocess.run(
                    ["bash", "-euo", "pipefail", "-c", text],
                    cwd=work, env=env, stdin=subprocess.DEVNULL,
                    capture_output=True, text=True, timeout=TIMEOUT_S,
                )
                rc, output = r.returncode, r.stdout + r.stderr
            except subprocess.TimeoutExpired as e:
                rc, output = "timeout", f"(no end after {TIMEOUT_S} s)\n{e.stdout or ''}{e.stderr or ''}"
            dt = time.monotonic() - t0
            status = "ok" if rc == 0 else f"FAILED ({rc})"
            print(f"  {status:>12} {dt:6.1f} s  {where}", flush=True)
            if rc != 0:
                failed.append(where)
                tail = "\n".join(str(output).splitlines()[-30:])
                print(f"--- block\n{text}--- output (last 30 lines)\n{tail}\n---", flush=True)
            shutil.rmtree(work, ignore_errors=True)
    if failed:
        print("doc commands FAILED: " + ", ".join(failed), file=sys.stderr)
        return 1
    print(f"doc commands: {len(todo)} blocks ran, {len(skipped)} skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
