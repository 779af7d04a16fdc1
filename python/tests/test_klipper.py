"""The Klipper + Trinamic accelerometer route from Python: the plan, the trial table and the
table step give what the CLI's `accel klipper-plan`, `klipper-trial` and `klipper-refine` give,
on logs the CLI's simulated Klipper printer writes (docs/accelerometer.md#refining-a-trinamic-table)."""

from pathlib import Path

import pytest

import stepdamp
from stepdamp import Profile, StepdampError

REAL = Path(__file__).resolve().parents[2] / "docs" / "profiles" / "patent-motor-real.toml"
AXIS = "tmc5160 stepper_x"
STEADY = ["--move", "M973 X F2 R6 H4 A0 B0 C0 D0", "--move", "M973 X F2 R-6 H4 A0 B0 C0 D0"]


def _log(cli, table, seed, out):
    rc, _, err = cli(
        "accel", "simulate-klipper", "--motor", REAL, "--current", "0.9", "--axis", AXIS,
        "--table", table, *STEADY, "--seed", seed, "--out", out,
    )
    assert rc == 0, err


def test_the_plan_and_the_trial_table_are_the_clis(cli, tmp_path):
    p = stepdamp.klipper_plan(AXIS, "corexy", 32.0, travel_mm=80.0)
    rc, out, err = cli("accel", "klipper-plan", "--axis", AXIS, "--kinematics", "corexy",
                       "--rotation-distance", "32", "--travel-mm", "80")
    assert rc == 0, err
    assert p["gcode"] == out
    m = p["moves"][0]
    # Motor A alone on CoreXY: x and y each 80 mm, 160 mm of belt at 64 mm/s.
    assert (m["dx_mm"], m["dy_mm"], m["motor_revs"]) == (80.0, 80.0, 5.0)
    t = stepdamp.klipper_trial_table(AXIS)
    rc, out, err = cli("accel", "klipper-trial", "--axis", AXIS, "--out", tmp_path / "trial.cfg")
    assert rc == 0, err
    assert t["block"] == (tmp_path / "trial.cfg").read_text()
    assert f"TRIAL_LOG={t['klipper_trial']}" in out
    assert abs(t["achieved_rad"] / 0.12 - 1) < 0.03 and t["harmonic"] == 4


def test_the_table_step_is_the_clis_and_names_the_floor(cli, tmp_path):
    t = stepdamp.klipper_trial_table(AXIS)
    (tmp_path / "trial.cfg").write_text(t["block"])
    base, trial = tmp_path / "base.json.gz", tmp_path / "trial.json.gz"
    _log(cli, "none", 1, base)
    _log(cli, tmp_path / "trial.cfg", 2, trial)
    h, u, phi = t["klipper_trial"].split(",")
    shift = (int(h), float(u), float(phi))
    r = stepdamp.klipper_refine([base, trial], Profile.load(REAL), AXIS, klipper_trials={trial: shift})
    rc, out, err = cli(
        "accel", "klipper-refine", "--log", base, "--log", trial, "--klipper-trial", f"{trial}={t['klipper_trial']}",
        "--motor", REAL, "--axis", AXIS, "--in-use", "none", "--out", tmp_path / "new.cfg",
    )
    assert rc == 0, err
    assert r["block"] == (tmp_path / "new.cfg").read_text()
    assert out.startswith(r["text"])
    assert r["harmonic"] == 4 and abs(r["new_rad"] - r["table"]["achieved_rad"]) < 0.002
    ways = sorted(p["direction"] for p in r["pairs"])
    assert ways == ["backward", "forward"]
    for p in r["pairs"]:
        # What is expected with the new table is at most the floor plus the noise.
        assert abs(p["predicted_m_s2"]) < abs(p["baseline_m_s2"]) / 5
        assert p["floor_m_s2"] <= abs(p["predicted_m_s2"]) + 1e-12
    # The new table in use: a second step reads it back as the table in use.
    (tmp_path / "new.cfg").write_text(r["block"])
    again = stepdamp.klipper_refine([base, trial], Profile.load(REAL), AXIS, klipper_trials={trial: shift},
                                    in_use=tmp_path / "new.cfg")
    assert abs(again["in_use_rad"] - r["table"]["achieved_rad"]) < 1e-12


def test_bad_arguments_are_refused_in_one_line(tmp_path):
    cases = [
        (lambda: stepdamp.klipper_plan("tmc2209 stepper_x", "cartesian", 40.0), "no wave table"),
        (lambda: stepdamp.klipper_plan(AXIS, "delta", 40.0), "cartesian or corexy"),
        (lambda: stepdamp.klipper_plan(AXIS, "cartesian", float("nan")), "rotation distance: NaN"),
        (lambda: stepdamp.klipper_trial_table(AXIS, harmonic=2), "orders 4, 8, 12, 16"),
        (lambda: stepdamp.klipper_trial_table(AXIS, shift_rad=float("inf")), "trial shift inf rad"),
        (lambda: stepdamp.klipper_refine(tmp_path / "missing.json.gz", Profile.load(REAL), AXIS,
                                         klipper_trials={}), "missing.json.gz"),
        (lambda: stepdamp.klipper_refine(tmp_path / "x.json.gz", Profile.load(REAL), AXIS,
                                         klipper_trials={tmp_path / "x.json.gz": (2, 0.1, 0.0)}), "orders 4, 8, 12, 16"),
    ]
    for call, want in cases:
        with pytest.raises(StepdampError) as e:
            call()
        msg = str(e.value)
        assert want in msg and "\n" not in msg, msg
