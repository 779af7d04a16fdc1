#!/usr/bin/env python3
"""Memory and time of ``stepdamp.identify`` on DataFrames against the CLI on the same logs.

    python scripts/bench-python-identify.py [--rows N] [--dir DIR]

Needs the ``stepdamp`` wheel installed in this interpreter (``python/ci.sh`` builds it) and
the CLI in ``STEPDAMP_BIN``. Simulates four servo runs of the patent motor at 20 kHz (``N``
rows in all, default 4,000,000: 50 s each), writes them as CSV (kept in ``DIR`` between runs
when given), then measures, each in its own fresh process:

- the CLI: ``stepdamp identify --log a.csv … --motor patent-motor``: wall time and peak RSS;
- Python: ``pandas.read_csv`` of the same files (the DataFrames a user would have), then
  ``stepdamp.identify`` on them: wall time of ``identify`` and the peak RSS it adds to the
  process that holds the DataFrames.

It prints both and the ratios (Python's ``identify`` over the CLI). The issue's bound is
Python ≤ the CLI plus the DataFrames themselves: peak added by identify ≤ CLI peak, identify
time ≤ CLI time. It reports; it never fails on a number (machines are shared and noisy).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import stepdamp

SPEEDS_RAD_S = (6.0, 11.0, -6.0, -11.0)
PWM_HZ = 20_000

PYTHON_SIDE = r"""
import sys, time, json
import pandas as pd
import stepdamp

def rss_mib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20

def hwm_mib():
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) for l in f if l.startswith("VmHWM:")) / 1024

frames = [pd.read_csv(p, engine="pyarrow") for p in sys.argv[1:]]
held = rss_mib()
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # resets the peak (VmHWM) to the RSS now: the reading's transient peak is not counted
base = stepdamp.Profile.preset("patent-motor")
t0 = time.perf_counter()
stepdamp.identify(frames, base)
dt = time.perf_counter() - t0
peak = hwm_mib()
print(json.dumps({"held_mib": held, "peak_mib": peak, "identify_s": dt,
                  "rows": sum(len(f) for f in frames)}))
"""


def write_logs(rows: int, folder: str) -> list:
    paths = [os.path.join(folder, f"run{i}.csv") for i in range(len(SPEEDS_RAD_S))]
    if all(os.path.exists(p) for p in paths):
        return paths
    motor = stepdamp.Profile.preset("patent-motor")
    duration_s = rows / len(SPEEDS_RAD_S) / PWM_HZ
    for i, (w, path) in enumerate(zip(SPEEDS_RAD_S, paths)):
        print(f"simulating run {i + 1}/{len(paths)}: {w} rad/s for {duration_s:.0f} s", file=sys.stderr)
        log = stepdamp.simulate(motor, "servo", "off", w, duration_s, current_noise_a=0.005, seed=i)
        log.to_csv(path, index=False, float_format="%.17g")
    return paths


def run_measured(cmd: list) -> tuple:
    """Runs ``cmd`` to its end; returns (stdout, wall s, peak RSS MiB of that process)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.stdout.read(), proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        sys.exit(f"{' '.join(cmd[:2])} failed ({status}): {err.strip()[-400:]}")
    return out, wall, usage.ru_maxrss / 1024


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=4_000_000, help="rows in all (default 4,000,000)")
    ap.add_argument("--dir", help="where to keep the logs between runs (default: a temporary folder)")
    a = ap.parse_args()
    if a.rows < 4 * PWM_HZ:
        ap.error(f"--rows {a.rows}: at least {4 * PWM_HZ} (1 s per run)")
    cli = os.environ.get("STEPDAMP_BIN")
    if not cli:
        sys.exit("set STEPDAMP_BIN to the stepdamp CLI (cargo build --release -p stepdamp)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = a.dir or tmp
        os.makedirs(folder, exist_ok=True)
        paths = write_logs(a.rows, folder)
        cmd = [cli, "identify", "--quiet", "--motor", "patent-motor", "--out", os.path.join(tmp, "found.toml")]
        for p in paths:
            cmd += ["--log", p]
        _, cli_s, cli_mib = run_measured(cmd)
        out, _, _ = run_measured([sys.executable, "-c", PYTHON_SIDE, *paths])
        py = json.loads(out.strip().splitlines()[-1])
    added = py["peak_mib"] - py["held_mib"]
    print(f"rows: {py['rows']}")
    print(f"CLI identify:            {cli_s:7.2f} s wall, peak RSS {cli_mib:8.1f} MiB (reading the CSV included)")
    print(f"Python, DataFrames held: {'':7} {'':9} RSS {py['held_mib']:8.1f} MiB")
    print(f"Python identify:         {py['identify_s']:7.2f} s wall, peak added {added:8.1f} MiB")
    print(f"ratio Python/CLI: time {py['identify_s'] / cli_s:.2f}, memory {added / cli_mib:.2f} (bound: ≤ 1 each)")


if __name__ == "__main__":
    main()
