"""The stepdamp Python API against the CLI (same Rust code, same numbers, same errors)."""

import copy
import json
import pickle

import numpy as np
import pandas as pd
import pytest

import stepdamp
from stepdamp import Profile, StepdampError


def test_presets_load_with_unit_named_attributes_and_round_trip_through_toml(tmp_path):
    p = Profile.preset("patent-motor")
    assert p.name == "patent-motor"
    assert (p.km_nm_per_a, p.pole_pairs, p.resistance_ohm, p.inertia_kg_m2) == (0.3, 50, 0.9, 4.0e-5)
    assert p.pwm_hz == 20000.0 and p.counts_per_rev == 4000 and p.topology == "three-leg"
    assert [h["order"] for h in p.detent] == [4, 2, 1]
    path = tmp_path / "m.toml"
    path.write_text(p.to_toml())
    assert Profile.load(path) == p
    assert Profile.from_toml(p.to_toml()) == p
    assert pickle.loads(pickle.dumps(p)) == p and copy.deepcopy(p) == p
    for name in stepdamp.PRESETS:
        assert Profile.preset(name).name == name


def test_setting_an_attribute_validates_and_keeps_the_old_value_on_error():
    p = Profile.preset("patent-motor")
    p.inertia_kg_m2 = 8e-5
    assert p.inertia_kg_m2 == 8e-5
    with pytest.raises(StepdampError, match="motor.resistance_ohm"):
        p.resistance_ohm = -1.0
    assert p.resistance_ohm == 0.9
    p.detent = [{"order": 4, "amplitude_nm": 0.01, "phase_rad": 0.1}]
    assert p.detent == [{"order": 4, "amplitude_nm": 0.01, "phase_rad": 0.1}]


def test_profile_errors_carry_the_clis_one_line_message(tmp_path, cli):
    bad = tmp_path / "bad.toml"
    bad.write_text(Profile.preset("patent-motor").to_toml().replace("resistance_ohm = 0.9", "resistance_ohm = -2.0"))
    with pytest.raises(StepdampError) as e:
        Profile.load(bad)
    rc, _, err = cli("motor", "check", bad)
    assert rc != 0 and err.strip() == f"error: {e.value}"
    with pytest.raises(StepdampError) as e:
        Profile.preset("nope")
    rc, _, err = cli("motor", "check", "nope")
    assert err.strip() == f"error: {e.value}"


def test_simulate_returns_the_run_log_columns_and_the_clis_metrics(cli):
    p = Profile.preset("patent-motor")
    log, m = stepdamp.simulate(p, "open-loop", "patent", speed_rad_s=8.4, duration_s=0.4, return_metrics=True)
    assert isinstance(log, pd.DataFrame)
    assert list(log.columns) == ["t_s", "theta_cmd_rad", "theta_fb_rad", "omega_fb_rad_s", "i_a_a", "i_b_a",
                                 "i_d_a", "i_q_a", "iq_cmd_a", "v_a_v", "v_b_v"]
    assert len(log) == 8000 and log["t_s"].iloc[1] == 1 / 20000
    rc, out, _ = cli("simulate", "--speed", 8.4, "--duration", 0.4, "--compensation", "patent")
    assert rc == 0
    assert f"rms {m['vel_err_rms_rad_s']:.4f} rad/s, pp {m['vel_err_pp_rad_s']:.4f} rad/s" in out


def test_simulate_columns_are_numpy_arrays_owning_one_buffer_each():
    p = Profile.preset("patent-motor")
    d = stepdamp.simulate(p, "servo", "off", 5.0, 0.3, as_frame=False)
    assert isinstance(d, dict) and set(d) >= {"t_s", "i_q_a"}
    for a in d.values():
        assert isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and len(a) == 6000
        # The Vec handed to numpy is the buffer (no numpy-side copy): its base is the Rust owner.
        assert a.base is not None and not isinstance(a.base, np.ndarray)


def test_a_sweep_table_and_summary_equal_the_clis_for_the_same_inputs(tmp_path, cli):
    p = Profile.preset("patent-motor")
    comps = "off,patent,estimated,angle"
    table, summary = stepdamp.sweep(p, "open-loop", comps, stepdamp.linear_grid(4.0, 8.4, 3), duration_s=0.5)
    args = ["sweep", "--mode", "open-loop", "--compensation", comps, "--from", 4.0, "--to", 8.4, "--points", 3,
            "--duration", 0.5, "--out", tmp_path]
    rc, out_json, err = cli(*args, "--format", "json")
    assert rc == 0, err
    ref = pd.read_csv(tmp_path / "sweep.csv", float_precision="round_trip")
    pd.testing.assert_frame_equal(table, ref, check_exact=True)
    assert len(table) == 12
    # The summary is the library's: the CLI's JSON key for key, and its printed text.
    assert dict(summary) == json.loads(out_json)
    rc, out_text, err = cli(*args)
    assert rc == 0, err
    assert str(summary) and str(summary) in out_text
    assert summary["resonances"][0] == {"order": 4, "speed_rad_s": p.resonance_speed_rad_s(4)}
    near_k4 = summary["modes"][0]["near_resonances"][0]
    assert near_k4["resonance"]["order"] == 4
    patent = [q for q in near_k4["peaks"] if q["compensation"] == "patent"][0]
    assert patent["vs_off"] > 1.0
    assert "k=4" in repr(summary)


def test_resonance_gives_the_clis_speeds(cli):
    p = Profile.preset("patent-motor")
    r = stepdamp.resonance(p)
    assert r["natural_frequency_rad_s"] == p.natural_frequency_rad_s()
    assert list(r["resonances_rad_s"]) == [4, 2, 1]
    rc, out, _ = cli("resonance", "--motor", "patent-motor")
    for k, w in r["resonances_rad_s"].items():
        assert f"k={k}" in out and f"{w:.3f} rad/s" in out


def test_ripple_equals_the_clis_json(cli, tmp_path):
    p = Profile.from_toml(Profile.preset("patent-motor").to_toml().replace(
        "\n[drive]", "\n[motor.flux]\nphase_b_gain = 0.03\n\n[[motor.flux.harmonic]]\norder = 3\n"
        "ratio = 0.01\nphase_rad = 0.2\n\n[drive]", 1))
    path = tmp_path / "real.toml"
    path.write_text(p.to_toml())
    r = stepdamp.ripple(p, 1.9, 0.0)
    rc, out, _ = cli("motor", "ripple", "--motor", str(path), "--id", "1.9", "--iq", "0", "--format", "json")
    assert rc == 0 and json.loads(out) == r
    # 3·h3·Km·I at order 4 in the current part (docs/design.md: to first order; g and h3
    # together add up to g·3h3·Km·I), the preset's 20 mN·m in the detent part.
    k4 = [h for h in r["current"] if h["order"] == 4][0]
    assert abs(k4["amplitude_nm"] - 3 * 0.01 * 0.3 * 1.9) < 0.03 * 3 * 0.01 * 0.3 * 1.9
    half = stepdamp.ripple(p, 0.95, 0.0)
    assert abs([h for h in half["current"] if h["order"] == 4][0]["amplitude_nm"] - k4["amplitude_nm"] / 2) < 1e-12
    assert [h for h in r["detent"] if h["order"] == 4][0]["amplitude_nm"] == 0.02
    with pytest.raises(stepdamp.StepdampError, match="--id 1e9 A"):
        stepdamp.ripple(p, 1e9, 0.0)


def _servo_logs(p):
    return [stepdamp.simulate(p, "servo", "off", w, 1.2, current_noise_a=0.005, seed=i)
            for i, w in enumerate([6.0, 11.0, -6.0, -11.0])]


def test_identification_from_dataframes_equals_identification_from_files(tmp_path):
    truth = Profile.preset("patent-motor")
    logs = _servo_logs(truth)
    paths = []
    for i, log in enumerate(logs):
        paths.append(tmp_path / f"run{i}.csv")
        log.to_csv(paths[-1], index=False, float_format="%.17g")
    base = truth.copy()
    base.detent = []
    found, report = stepdamp.identify(logs, base, orders=[1, 2, 4])
    from_files, _ = stepdamp.identify(paths, base, orders=[1, 2, 4])
    assert found.detent == from_files.detent
    a4 = [h for h in found.detent if h["order"] == 4][0]["amplitude_nm"]
    assert abs(a4 - 0.02) < 0.002, report
    assert [h["order"] for h in report["harmonics"]] == [1, 2, 4]
    assert report["harmonics"][2]["amplitude_nm"]["ci95"] > 0
    assert len(report["runs"]) == 4
    # A dict of arrays works as well.
    d_found, _ = stepdamp.identify([{c: log[c].to_numpy() for c in log} for log in logs], base, orders=[1, 2, 4])
    assert d_found.detent == found.detent


def test_sensorless_identification_from_open_loop_dataframes():
    # The runs of `stepdamp identify plan --sensorless --motor patent-motor` (shortened):
    # standstill 0.2 s, ramp 0.2 s, two speeds in both directions; no encoder column.
    truth = Profile.preset("patent-motor")
    logs = []
    for i, w in enumerate([0.74, -0.74, 1.48, -1.48]):
        log = stepdamp.simulate(truth, "open-loop", "off", w, 2.4, dwell_s=0.2, ramp_s=0.2,
                                current_noise_a=0.005, seed=i + 1)
        logs.append(log[["t_s", "theta_cmd_rad", "i_a_a", "i_b_a", "v_a_v", "v_b_v"]])
    base = truth.copy()
    base.detent = []
    base.resistance_ohm = 0.99
    found, report = stepdamp.identify(logs, base, orders=[1, 2, 4])
    assert report["route"] == "sensorless"
    assert abs(report["resistance_ohm"] / 0.9 - 1) < 1e-3
    assert abs(found.resistance_ohm / 0.9 - 1) < 1e-3
    a4 = [h for h in found.detent if h["order"] == 4][0]["amplitude_nm"]
    assert abs(a4 - 0.02) < 0.001, report


def test_rust_errors_become_exceptions_with_one_line_messages():
    p = Profile.preset("patent-motor")
    cases = [
        (lambda: stepdamp.simulate(p, "sideways", "off", 5.0, 0.5), "mode 'sideways'"),
        (lambda: stepdamp.simulate(p, "open-loop", "maybe", 5.0, 0.5), "expected off, patent, estimated, angle, table"),
        (lambda: stepdamp.simulate(p, "servo", "estimated", 5.0, 0.5), "estimated"),
        (lambda: stepdamp.simulate(p, "open-loop", "off", 5.0, 0.05), "duration"),
        (lambda: stepdamp.sweep(p, "open-loop", "off", []), "speeds"),
        (lambda: stepdamp.identify([pd.DataFrame({"t_s": [0.0, 1.0]})], p), "missing column"),
        (lambda: Profile.load("/nonexistent/motor.toml"), "no such profile file"),
        (lambda: Profile.load("nope"), "unknown motor 'nope'"),
    ]
    for call, needle in cases:
        with pytest.raises(StepdampError) as e:
            call()
        assert needle in str(e.value) and "\n" not in str(e.value)
        assert isinstance(e.value, ValueError)
