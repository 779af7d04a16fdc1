"""Prusa's influence step from Python: `prusa_refine` gives what `stepdamp accel refine` prints
and writes, from the same library call (docs/accelerometer.md#refining-from-captures)."""

import math
from pathlib import Path

import pytest

import stepdamp
from stepdamp import Profile, StepdampError

REAL = Path(__file__).resolve().parents[2] / "docs" / "profiles" / "patent-motor-real.toml"
BASE = "M973 X F2 R10 H4 A0 B0 C0 D0"
TRIAL = "M973 X F2 R10 H4 A0 B0 C0.01 D0.01"


def _simulate(cli, gcode, table, seed, out, current="0.9"):
    code, _, err = cli("accel", "simulate", "--motor", REAL, "--current", current, "--gcode", gcode,
                       "--in-use", table, "--echo", "--seed", seed, "--out", out)
    assert code == 0, err
    return Path(out).read_text()


def _session(cli, tmp_path, current="0.9"):
    session = tmp_path / "session.log"
    session.write_text(_simulate(cli, BASE, "none", "1", tmp_path / "b.txt", current)
                       + _simulate(cli, TRIAL, "none", "2", tmp_path / "t.txt", current))
    return session


def test_prusa_refine_gives_the_clis_report_and_table_and_a_step_without_a_trial(cli, tmp_path):
    session, new = _session(cli, tmp_path), tmp_path / "new.gcode"
    code, stdout, err = cli("accel", "refine", "--log", session, "--motor", REAL, "--in-use", "none", "--axis", "X",
                            "--current", "0.9", "--out", new)
    assert code == 0, err
    motor = Profile.load(REAL)
    got = stepdamp.prusa_refine(session, motor, "X", current_peak_a=0.9)
    assert got["text"] in stdout
    assert got["gcode"] == new.read_text()
    [s] = got["steps"]
    assert (s["harmonic"], s["direction"], s["speed_rev_s"]) == (4, "backward", -2.0)
    assert s["carried_current_ratio"] is None and isinstance(s["trial_m_s2"], complex)
    assert abs(s["baseline_m_s2"]) == pytest.approx(1.4731, abs=1e-4)
    assert s["in_use"] == (0.0, 0.0) and s["item"][0] > 0

    # The second step: the baseline alone with the table loaded, the first session's influence.
    b2, new2 = tmp_path / "b2.txt", tmp_path / "new2.gcode"
    _simulate(cli, BASE, new, "3", b2)
    code, stdout, err = cli("accel", "refine", "--log", b2, "--influence-from", session, "--influence-current", "0.9",
                            "--motor", REAL, "--in-use", new, "--axis", "X", "--current", "0.9", "--out", new2)
    assert code == 0, err
    got2 = stepdamp.prusa_refine([b2], motor, "x", current_peak_a=0.9, in_use=new, influence_from=session,
                                 influence_current_peak_a=0.9)
    assert got2["text"] in stdout
    assert got2["gcode"] == new2.read_text()
    [s2] = got2["steps"]
    assert s2["trial_m_s2"] is None and s2["trial_radius95_m_s2"] is None
    assert s2["carried_current_ratio"] == 1.0
    assert s2["influence_m_s2_per_rad"] == s["influence_m_s2_per_rad"]
    assert s2["in_use"] == pytest.approx(s["item"], abs=1e-5)
    assert abs(s2["baseline_m_s2"]) < abs(s["baseline_m_s2"]) / 10


def test_prusa_refine_refuses_what_the_cli_refuses_naming_pythons_arguments(cli, tmp_path):
    session, motor = _session(cli, tmp_path), Profile.load(REAL)
    for kwargs, needle in [
        ({"influence_current_peak_a": 0.9}, "without influence_from"),
        ({"influence_from": session}, "the run current is needed: influence_current_peak_a"),
        ({"influence_from": session, "influence_current_peak_a": -1.0}, "influence_current_peak_a -1"),
        ({"influence_from": session, "influence_current_peak_a": 0.9, "influence_current_rms_a": 0.6},
         "one of the two, not both"),
        ({"influence_from": session, "influence_current_peak_a": 0.3}, "at most 2× either way"),
        ({"timing": "sometimes"}, 'timing "sometimes"'),
        ({"mm_per_rev": math.nan}, "mm_per_rev NaN"),
        ({"mm_per_rev": 1000.0}, "mm_per_rev 1000: must be in 6.3..=314 mm"),
        ({"in_use": tmp_path / "missing.gcode"}, "missing.gcode"),
    ]:
        with pytest.raises(StepdampError, match=needle):
            stepdamp.prusa_refine(session, motor, "X", current_peak_a=0.9, **kwargs)
    with pytest.raises(StepdampError, match='axis "Z"'):
        stepdamp.prusa_refine(session, motor, "Z", current_peak_a=0.9)
    with pytest.raises(StepdampError, match="the run current is needed"):
        stepdamp.prusa_refine(session, motor, "X")


def test_a_table_too_large_for_the_firmware_raises_with_the_current_where_it_would_fit(cli, tmp_path):
    # docs/accelerometer.md#when-the-table-is-too-small: at 0.35 A the table needs 159 of 127.
    session = _session(cli, tmp_path, current="0.35")
    code, _, err = cli("accel", "refine", "--log", session, "--motor", REAL, "--in-use", "none", "--axis", "X",
                       "--current", "0.35", "--out", tmp_path / "x.gcode")
    assert code != 0 and "M906 X311" in err
    with pytest.raises(StepdampError, match="M906 X311") as e:
        stepdamp.prusa_refine(session, Profile.load(REAL), "X", current_rms_a=0.35 / math.sqrt(2))
    assert str(e.value).strip() in err
