#!/usr/bin/env bash
# The tolerance study of docs/python.md: 1000 variants of patent-motor on a Dask
# LocalCluster (python/examples/patent-motor-study.toml), its CDF plot as
# docs/generated/study-cdf.png, the Parquet table and summary under out/study/.
#
#   bash scripts/study.sh                      # LocalCluster, 2 worker processes
#   SCHEDULER=tcp://HOST:8786 bash scripts/study.sh   # an existing Dask cluster
#   VENV=path/to/venv bash scripts/study.sh    # a venv with stepdamp[study] installed
#
# Needs the Python package: `bash python/ci.sh` leaves a venv with it at
# target/python-ci/venv (the default here).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${VENV:-$root/target/python-ci/venv}"
spec="${SPEC:-$root/python/examples/patent-motor-study.toml}"
out="${OUT:-$root/out/study}"
# Dask starts its worker processes by spawning: the driver must be an importable file
# with a main guard, not standard input.
driver=$(mktemp --suffix=.py)
trap 'rm -f "$driver"' EXIT
cat > "$driver" <<'PY'
import sys

import stepdamp


def main():
    spec, out, png, scheduler, workers = sys.argv[1:6]
    r = stepdamp.study(spec, scheduler=scheduler or None, n_workers=int(workers), threads_per_worker=1,
                       chunk_size=25, out=out)
    r.plot_cdf(png, dpi=60)
    print(r.report)
    for p in r.summary["pairs"]:
        print(f"{p['mode']} {p['compensation']}: ≥ {r.summary['threshold']:g}x at every resonance in "
              f"{100 * p['share_hold_all']:.1f} % of variants")
    where = scheduler or f"LocalCluster, {workers} worker processes"
    print(f"{len(r.table)} variants in {r.wall_s:.1f} s wall: {r.variants_per_s:.2f} variants/s ({where})")
    print(f"wrote {out}/study.parquet, {out}/study-cdf.png, {out}/study-summary.json, {png}")


if __name__ == "__main__":
    main()
PY
"$venv/bin/python" "$driver" "$spec" "$out" "$root/docs/generated/study-cdf.png" "${SCHEDULER:-}" "${WORKERS:-2}"
