"""Tolerance studies: does compensation hold across production tolerances?

``study(spec)`` draws the spec's motor variants, runs each one's sweep around its own
resonances with and without compensation (Rust, ``stepdamp-study``: the same code as
``stepdamp study --spec``), and reports the distribution of the reduction (peak-to-peak
velocity error off / on) at each resonance. The variants are spread over Dask: with no
address a ``LocalCluster`` on this machine, ``scheduler="tcp://HOST:8786"`` or
``client=Client(...)`` for a real cluster, one task per chunk of variants; ``dask=False``
runs in this process (on all cores). Variant ``i`` depends only on the study seed and
``i``, so the table does not depend on how the work is split.
"""

from __future__ import annotations

import importlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from typing import Any, Union

import numpy as np

from . import _native

__all__ = ["StudyResult", "load_spec", "study", "run_chunk"]


def load_spec(spec: Union[str, "os.PathLike[str]"]) -> str:
    """Reads and checks a study spec: a file path, or TOML text (anything with a newline).
    Returns the study as JSON (what travels to the workers: the motor profile is inside, so
    workers need no access to the spec's files)."""
    if isinstance(spec, str) and "\n" in spec:
        return _native.study_from_toml(spec, "<study spec>", os.getcwd())
    return _native.study_load(os.fspath(spec))


def run_chunk(study_json: str, start: int, stop: int) -> dict:
    """Runs variants ``start..stop`` (the task each Dask worker runs): a dict of numpy
    columns, rows in variant order."""
    return _native.study_run_range(study_json, int(start), int(stop))


@dataclass
class StudyResult:
    """The results of a study.

    ``table``: one row per variant (pandas DataFrame): ``variant``, the drawn parameters
    (profile key names, SI units; ``controller_…`` for the controller's model when it has
    its own error), ``resonance_k{k}_rad_s``, ``pp_{mode}_{comp}_k{k}_rad_s`` (peak-to-peak
    velocity error near resonance ``k``), ``lost_sync_{mode}_{comp}`` (runs that slipped),
    ``reduction_{mode}_{comp}_k{k}`` (off / on). ``summary``: percentiles, shares (0–1) and
    worst variants (dict). ``report``: the printed summary. ``wall_s``: wall time of the
    runs in s.
    """

    table: Any
    summary: dict
    report: str
    wall_s: float
    study_json: str = field(repr=False)

    @property
    def variants_per_s(self) -> float:
        """Variants simulated per wall-clock second."""
        return len(self.table) / self.wall_s if self.wall_s > 0 else math.nan

    def __str__(self) -> str:
        return self.report

    def to_parquet(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Writes the table as Parquet (pyarrow)."""
        _extra("pyarrow")
        self.table.to_parquet(os.fspath(path), engine="pyarrow", index=False)

    def plot_cdf(self, path: Union[str, "os.PathLike[str]", None] = None, dpi: int = 80):
        """Plots the CDF of the reduction at each resonance, one panel per resonance, one
        curve per mode and compensation (log x axis; the threshold and 1× marked). Saves
        to ``path`` when given; returns the matplotlib figure."""
        matplotlib = _extra("matplotlib")
        if path is not None:
            matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        pairs = self.summary["pairs"]
        orders = [r["order"] for r in pairs[0]["resonances"]] if pairs else []
        fig, axes = plt.subplots(1, max(1, len(orders)), figsize=(4.2 * max(1, len(orders)), 3.4), squeeze=False)
        thr = self.summary["threshold"]
        for ax, (g, k) in zip(axes[0], enumerate(orders)):
            for p in pairs:
                col = f"reduction_{p['mode']}_{p['compensation']}_k{k}"
                x = np.sort(np.nan_to_num(self.table[col].to_numpy(dtype=float), nan=0.0))
                x = np.clip(x, 1e-2, 1e4)
                y = np.arange(1, len(x) + 1) / len(x)
                ax.step(x, y, where="post", label=f"{p['mode']} {p['compensation']}")
            ax.axvline(thr, color="0.4", ls="--", lw=0.8)
            ax.axvline(1.0, color="r", ls=":", lw=0.8)
            ax.set_xscale("log")
            ax.set_title(f"k={k} ({pairs[0]['resonances'][g]['nominal_speed_rad_s']:.2f} rad/s nominal)")
            ax.set_xlabel("reduction of pp velocity error (off / on)")
            ax.grid(True, which="both", alpha=0.3)
        axes[0][0].set_ylabel("share of variants ≤ x")
        axes[0][0].legend(fontsize=8, loc="upper left")
        fig.suptitle(f"{self.summary['motor']}: {self.summary['variants']} variants", fontsize=10)
        fig.tight_layout()
        if path is not None:
            fig.savefig(os.fspath(path), dpi=dpi)
        return fig


def _extra(module: str):
    """Imports ``module`` of the ``[study]`` extra; if it is missing, the error names the
    extra and the command that installs it."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ModuleNotFoundError(
            f"stepdamp.study needs the optional [study] extra ({module} is missing): "
            "pip install 'stepdamp[study]'",
            name=module,
        ) from e


def _chunks(n: int, size: int):
    return [(lo, min(n, lo + size)) for lo in range(0, n, size)]


def study(
    spec: Union[str, "os.PathLike[str]"],
    *,
    client: Any = None,
    scheduler: Union[str, None] = None,
    dask: bool = True,
    n_workers: Union[int, None] = None,
    threads_per_worker: Union[int, None] = None,
    processes: bool = True,
    chunk_size: int = 25,
    out: Union[str, "os.PathLike[str]", None] = None,
) -> StudyResult:
    """Runs a tolerance study.

    ``spec``: a study spec file or TOML text (format in ``docs/python.md``). Where it runs:
    ``client`` (a ``dask.distributed.Client``), else ``scheduler`` (``"tcp://HOST:8786"``),
    else a ``LocalCluster(n_workers, threads_per_worker, processes)`` started and closed
    here; ``dask=False`` runs in this process on all cores. ``chunk_size`` variants per
    Dask task. ``out``: a directory to write ``study.parquet``, ``study-cdf.png`` and
    ``study-summary.json`` into.
    """
    # The extra's modules this call needs, before any work.
    pd = _extra("pandas")
    if dask:
        distributed = _extra("dask.distributed")
    if out is not None:
        _extra("pyarrow")
        _extra("matplotlib")
    study_json = load_spec(spec)
    n, columns = _native.study_info(study_json)
    if not (isinstance(chunk_size, int) and chunk_size >= 1):
        raise ValueError(f"chunk_size={chunk_size!r}: must be an integer ≥ 1")
    chunks = _chunks(n, chunk_size)
    t0 = time.perf_counter()
    if not dask:
        parts = [run_chunk(study_json, lo, hi) for lo, hi in chunks]
    else:
        Client, LocalCluster = distributed.Client, distributed.LocalCluster
        own_cluster = own_client = None
        try:
            if client is None:
                if scheduler is not None:
                    client = own_client = Client(scheduler)
                else:
                    own_cluster = LocalCluster(
                        n_workers=n_workers, threads_per_worker=threads_per_worker, processes=processes,
                        dashboard_address=None,
                    )
                    client = own_client = Client(own_cluster)
            futures = [client.submit(run_chunk, study_json, lo, hi, pure=False) for lo, hi in chunks]
            parts = client.gather(futures)
        finally:
            if own_client is not None:
                own_client.close()
            if own_cluster is not None:
                own_cluster.close()
    wall = time.perf_counter() - t0
    merged = {c: np.concatenate([p[c] for p in parts]) if parts else np.empty(0) for c in columns}
    order = np.argsort(merged["variant"], kind="stable")
    merged = {c: v[order] for c, v in merged.items()}
    summary_json, report = _native.study_summarize(study_json, {c: v.tolist() for c, v in merged.items()})
    table = pd.DataFrame(merged, copy=False)
    table["variant"] = table["variant"].astype(np.int64)
    result = StudyResult(table=table, summary=json.loads(summary_json), report=report, wall_s=wall,
                         study_json=study_json)
    if out is not None:
        os.makedirs(out, exist_ok=True)
        result.to_parquet(os.path.join(out, "study.parquet"))
        result.plot_cdf(os.path.join(out, "study-cdf.png"))
        with open(os.path.join(out, "study-summary.json"), "w", encoding="utf-8") as f:
            json.dump(result.summary, f, indent=1)
    return result
