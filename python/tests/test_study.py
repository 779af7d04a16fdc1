"""Tolerance studies: the same table in-process, on a Dask cluster of processes, and from the CLI."""

import json

import numpy as np
import pandas as pd
import pytest

import stepdamp
from stepdamp import StepdampError

SPEC = """
motor = "patent-motor"
variants = {n}
seed = 11
[sweep]
compensations = ["patent", "estimated"]
orders = [4, 2]
points = 1
duration_s = 0.4
[plant]
resistance_ohm = {{ scale = [0.9, 1.1] }}
inductance_h = {{ scale = [0.9, 1.1] }}
km_nm_per_a = {{ scale = [0.9, 1.1] }}
inertia_kg_m2 = {{ scale = [0.8, 1.5] }}
detent_amplitude_nm = {{ scale = [0.8, 1.2] }}
detent_phase_rad = {{ add = [-0.2, 0.2] }}
coulomb_friction_nm = {{ scale = [0.5, 1.5] }}
load_torque_nm = {{ uniform = [0.0, 0.005] }}
[controller_error]
detent_amplitude_nm = {{ scale = [0.95, 1.05] }}
[report]
worst = 3
"""


def test_a_200_variant_study_gives_the_same_table_on_a_2_worker_cluster_and_in_process(tmp_path):
    spec = tmp_path / "study.toml"
    spec.write_text(SPEC.format(n=200))
    local = stepdamp.study(spec, dask=False)
    dist = stepdamp.study(spec, n_workers=2, threads_per_worker=1, processes=True, chunk_size=17,
                          out=tmp_path / "out")
    assert len(local.table) == 200 and list(local.table["variant"]) == list(range(200))
    pd.testing.assert_frame_equal(local.table, dist.table, check_exact=True)
    assert local.summary == dist.summary and local.report == dist.report
    # The outputs: Parquet that reads back to the same table, the CDF plot, the summary.
    back = pd.read_parquet(tmp_path / "out" / "study.parquet")
    pd.testing.assert_frame_equal(back, dist.table, check_exact=True)
    assert (tmp_path / "out" / "study-cdf.png").stat().st_size > 1000
    assert json.loads((tmp_path / "out" / "study-summary.json").read_text()) == dist.summary
    # The summary describes this table.
    p = [q for q in local.summary["pairs"] if q["compensation"] == "patent"][0]
    red = local.table[[f"reduction_open-loop_patent_k{k}" for k in (4, 2)]].fillna(0.0)
    assert p["share_hold_all"] == pytest.approx((red.min(axis=1) >= 10.0).mean(), abs=0)
    assert p["resonances"][0]["percentiles"][4][1] == pytest.approx(np.percentile(red.iloc[:, 0], 50), rel=1e-12)
    worst = p["worst"][0]
    assert worst["min_reduction"] == red.min(axis=1).min()
    assert dict(worst["params"])["inertia_kg_m2"] == local.table.loc[worst["variant"], "inertia_kg_m2"]
    assert local.variants_per_s > 0


def test_a_client_passed_in_runs_the_study_and_any_chunking_gives_the_same_table(tmp_path):
    from dask.distributed import Client, LocalCluster

    spec = SPEC.format(n=12)
    base = stepdamp.study(spec, dask=False, chunk_size=12)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as c, Client(c) as cl:
        other = stepdamp.study(spec, client=cl, chunk_size=5)
    pd.testing.assert_frame_equal(base.table, other.table, check_exact=True)


def test_the_cli_and_python_run_the_same_study(tmp_path, cli):
    spec = tmp_path / "study.toml"
    spec.write_text(SPEC.format(n=10))
    rc, out, err = cli("study", "--spec", spec, "--out", tmp_path / "cli")
    assert rc == 0, err
    ref = pd.read_csv(tmp_path / "cli" / "study.csv", float_precision="round_trip")
    py = stepdamp.study(spec, dask=False)
    pd.testing.assert_frame_equal(py.table, ref, check_exact=True, check_dtype=False)
    assert py.report in out


def test_a_bad_spec_raises_the_clis_message(tmp_path, cli):
    spec = tmp_path / "bad.toml"
    spec.write_text('motor = "patent-motor"\nvariants = 5\n[plant]\nresistance = { scale = [0.9, 1.1] }\n')
    with pytest.raises(StepdampError) as e:
        stepdamp.study(spec, dask=False)
    rc, _, err = cli("study", "--spec", spec, "--out", tmp_path / "o")
    assert rc != 0 and err.strip() == f"error: {e.value}"
