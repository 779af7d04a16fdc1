"""The accelerometer route from Python: captures read as the CLI reads them, and the ripple
identified as `stepdamp identify --accel` identifies it (docs/accelerometer.md)."""

import gzip
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import stepdamp
from stepdamp import Profile, StepdampError

DATA = Path(__file__).parent / "data"
REAL = Path(__file__).resolve().parents[2] / "docs" / "profiles" / "patent-motor-real.toml"
# The capture python/tests/data/README.md says how to make again.
M973 = DATA / "m973-x-f2-r2-h4-c0.01.txt"
M973_GCODE = "M973 X F2 R2 H4 A0 B0 C0.01 D0.01"


def _printed(path):
    """The samples and annotations as printed, parsed here independently of the library."""
    samples, notes = [], {}
    for line in Path(path).read_text().splitlines():
        if line.startswith("Send: "):
            continue
        if ": " in line:
            k, v = line.split(": ", 1)
            notes[k] = v.strip()
        else:
            i, v = line.split(", ")
            assert int(i) == len(samples)
            samples.append(float(v))
    return np.array(samples), notes


def test_a_prusa_capture_reads_back_its_samples_annotations_and_commanded_motion():
    (c,) = stepdamp.read_accel_captures(M973)
    samples, notes = _printed(M973)
    assert c["format"] == "prusa" and c["gcode"] == M973_GCODE and c["axis"] == "X"
    assert c["line"] == 2 and c["source"] == str(M973)
    np.testing.assert_array_equal(c["accel_m_s2"], samples)
    a = c["annotations"]
    assert a["sampling_freq_hz"] == c["sampling_freq_hz"] == float(notes["sampling_freq"])
    assert a["movement_ok"] is (notes["movement_ok"] == "true") and a["accel_error"] == int(notes["accel_error"])
    for key in ("start_marker", "end_marker", "signal_start", "signal_end"):
        assert a[key + "_s"] == float(notes[key])
    assert a["valid"]
    # Sample k at k / rate (the CLI's reconstruction); R > 0 runs the phase down: backward,
    # at 2 rev/s and 2π·50·2 rad/s of electrical angle inside the constant-speed window.
    n = len(samples)
    for k in ("t_s", "theta_e_rad", "speed_rev_s", "accel_rev_s2", "motor_rev"):
        assert c[k].dtype == np.float64 and c[k].shape == (n,)
    np.testing.assert_allclose(c["t_s"], np.arange(n) / c["sampling_freq_hz"], rtol=0, atol=1e-12)
    assert c["direction"] == "backward"
    inside = (c["t_s"] > a["signal_start_s"]) & (c["t_s"] < a["signal_end_s"])
    assert inside.sum() > 1000
    np.testing.assert_allclose(c["speed_rev_s"][inside], -2.0, atol=1e-12)
    slope = np.polyfit(c["t_s"][inside], c["theta_e_rad"][inside], 1)[0]
    assert slope == pytest.approx(-2 * math.pi * 50 * 2, rel=1e-9)
    # 100 periods per revolution rebuild the same motion with twice the angle.
    (c100,) = stepdamp.read_accel_captures(M973, periods_per_rev=100)
    np.testing.assert_allclose(c100["theta_e_rad"], 2 * c["theta_e_rad"], rtol=1e-12, atol=1e-9)


def test_a_capture_whose_gcode_the_host_did_not_echo_has_samples_but_no_motion(tmp_path):
    bare = tmp_path / "bare.txt"
    bare.write_text("".join(l for l in M973.read_text().splitlines(True) if not l.startswith("Send: ")))
    (c,) = stepdamp.read_accel_captures(bare)
    assert c["gcode"] is None and c["direction"] is None and c["line"] == 1
    assert all(c[k] is None for k in ("t_s", "theta_e_rad", "speed_rev_s", "accel_rev_s2", "motor_rev"))
    assert len(c["accel_m_s2"]) == len(_printed(M973)[0])


def test_a_bad_sample_line_is_refused_naming_the_file_the_line_and_the_text(tmp_path):
    lines = M973.read_text().splitlines(True)
    lines[9] = "8, 0.0x1\n"
    bad = tmp_path / "bad.txt"
    bad.write_text("".join(lines))
    with pytest.raises(StepdampError) as e:
        stepdamp.read_accel_captures(bad)
    msg = str(e.value)
    assert f"{bad}:10: `8, 0.0x1`" in msg and "\n" not in msg, msg
    with pytest.raises(StepdampError, match=f"{bad}:10: "):
        stepdamp.identify_accel([bad], Profile.load(REAL), "X", current_peak_a=0.9)


def test_annotations_that_do_not_match_the_echoed_gcode_are_refused_as_identify_refuses_them(tmp_path):
    wrong = tmp_path / "wrong.txt"
    wrong.write_text(M973.read_text().replace("Send: M973 X F2 R2", "Send: M973 X F2 R4"))
    with pytest.raises(StepdampError, match=r"wrong.txt:2: end_marker printed 1.85 but `M973 X F2 R4"):
        stepdamp.read_accel_captures(wrong)


def _klipper_log(path, *, full_steps=200, seconds=2.0, rev_s=1.0, microsteps=16, offset=8):
    """A motion-analysis log as data_logger.py frames it (docs/files.md#klippers-motion-analysis-logs):
    the configuration, one stepper queue block at constant speed (counting up) and 1 kHz
    accelerometer samples from 0.5 s before to 0.5 s after it, x = 1000·t mm/s²."""
    steps_per_s = rev_s * full_steps * microsteps
    n = int(seconds * steps_per_s)
    clock_hz, interval = 1000 * steps_per_s, 1000
    t0 = 1.0
    stepper = {"microsteps": microsteps, "full_steps_per_rotation": full_steps}
    settings = {"printer": {"kinematics": "cartesian"}, "stepper_x": stepper, "tmc2209 stepper_x": {}}
    status = {"configfile": {"settings": settings}, "tmc2209 stepper_x": {"mcu_phase_offset": offset}}
    msgs = [{"id": "status", "result": {"status": status}}]
    first_clock = int(t0 * clock_hz)
    msgs.append({"q": "stepq:stepper_x", "params": {
        "data": [[interval, n, 0]], "start_mcu_position": 0,
        "first_clock": first_clock, "first_step_time": t0,
        "last_clock": first_clock + (n - 1) * interval, "last_step_time": t0 + (n - 1) / steps_per_s,
    }})
    times = np.arange(int((seconds + 1.0) * 1000)) / 1000 + t0 - 0.5
    for b in range(0, len(times), 100):
        data = [[float(t), 1000.0 * float(t), 5.0, 9810.0] for t in times[b:b + 100]]
        msgs.append({"q": "accelerometer:adxl345", "params": {"data": data, "errors": 0, "overflows": 0}})
    with gzip.open(path, "wb") as f:
        for m in msgs:
            f.write(json.dumps(m).encode() + b"\x03")
    return times


def test_a_klipper_log_is_cut_into_its_steady_stretch_with_the_logs_times_and_angles(tmp_path):
    log = tmp_path / "LOG.json.gz"
    times = _klipper_log(log)
    (s,) = stepdamp.read_accel_captures(log, trial=(4, 0.12, 0.0))
    assert s["format"] == "klipper" and s["direction"] == "forward" and s["source"] == str(log)
    info = s["log"]
    assert (info["stepper"], info["accelerometer"], info["kinematics"]) == ("stepper_x", "accelerometer:adxl345", "cartesian")
    assert (info["microsteps"], info["periods_per_rev"], info["mcu_phase_offset"]) == (16, 50, 8)
    assert info["trial"] == (4, 0.12, 0.0) and info["samples"] == len(times) and info["steps"] == 6400
    start, stop = s["range"]
    # Exact: the reader parses with serde_json's float_roundtrip (without it, 14 % of these
    # times came back one ulp off Python's shortest repr).
    np.testing.assert_array_equal(s["t_s"], times[start:stop])
    np.testing.assert_allclose(s["accel_m_s2"], times[start:stop], rtol=1e-12)  # 1000·t mm/s² = t m/s²
    # The settle time cut from each end of the move, 1.0–3.0 s.
    assert s["t_s"][0] >= 1.2 and s["t_s"][-1] <= 2.8 and s["t_s"][-1] - s["t_s"][0] > 1.5
    assert s["sampling_freq_hz"] == pytest.approx(1000.0, rel=1e-9)
    np.testing.assert_allclose(s["speed_rev_s"], 1.0, rtol=1e-9)
    slope = np.polyfit(s["t_s"], s["theta_e_rad"], 1)[0]
    assert slope == pytest.approx(2 * math.pi * 50, rel=1e-9)


def test_klipper_logs_whose_steps_per_rotation_differ_from_the_motor_are_refused_naming_the_log(tmp_path):
    log = tmp_path / "LOG.json.gz"
    _klipper_log(log, full_steps=400)
    with pytest.raises(StepdampError, match=r"LOG.json.gz: full_steps_per_rotation 400 is 100 electrical periods"):
        stepdamp.identify_accel(log, Profile.load(REAL), "X", current_peak_a=0.9)


def test_mixed_kinds_trials_of_other_files_and_a_missing_current_are_refused(tmp_path):
    log = tmp_path / "LOG.json.gz"
    _klipper_log(log)
    motor = Profile.load(REAL)
    with pytest.raises(StepdampError, match="Klipper logs .gzip. and Prusa captures .text. mixed"):
        stepdamp.identify_accel([log, M973], motor, "X", current_peak_a=0.9)
    with pytest.raises(StepdampError, match="is not one of the paths"):
        stepdamp.identify_accel([log], motor, "X", current_peak_a=0.9, klipper_trials={tmp_path / "x": (4, 0.1, 0)})
    with pytest.raises(StepdampError, match="kinematics goes with Prusa captures"):
        stepdamp.identify_accel([log], motor, "X", current_peak_a=0.9, kinematics="corexy")
    with pytest.raises(StepdampError, match='kinematics "delta": cartesian or corexy'):
        stepdamp.identify_accel([M973], motor, "X", current_peak_a=0.9, kinematics="delta")
    with pytest.raises(StepdampError, match="Prusa captures carry their trial in M973"):
        stepdamp.identify_accel([M973], motor, "X", current_peak_a=0.9, klipper_trials={M973: (4, 0.1, 0)})
    with pytest.raises(StepdampError, match="trial goes with Klipper logs"):
        stepdamp.read_accel_captures(M973, trial=(4, 0.1, 0.0))
    with pytest.raises(StepdampError, match="the run current is needed"):
        stepdamp.identify_accel([M973], motor, "X")
    with pytest.raises(StepdampError, match='axis "Z": '):
        stepdamp.identify_accel([M973], motor, "Z", current_peak_a=0.9)
    with pytest.raises(StepdampError, match="moved the other axis"):
        stepdamp.identify_accel([M973], motor, "Y", current_peak_a=0.9)


# The session of docs/accelerometer.md#identifying-the-ripple-from-captures: an M974 sweep and
# an M973 pair per direction on the simulated printer at 0.9 A.
SESSION = [
    ("M974 X A2 B4 R-8", 1),
    ("M974 X A2 B4 R8", 2),
    ("M973 X F2 R-6 H4 A0 B0 C0 D0", 3),
    ("M973 X F2 R-6 H4 A-0.0027 B-0.0027 C0.03 D0.03", 4),
    ("M973 X F2 R6 H4 A0 B0 C0 D0", 5),
    ("M973 X F2 R6 H4 A-0.0027 B-0.0027 C0.03 D0.03", 6),
]


@pytest.fixture(scope="module")
def session(cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("session")
    parts = []
    for gcode, seed in SESSION:
        out = d / f"c{seed}.txt"
        code, _, err = cli("accel", "simulate", "--motor", REAL, "--current", "0.9", "--gcode", gcode,
                           "--in-use", "none", "--echo", "--seed", seed, "--out", out)
        assert code == 0, err
        parts.append(out.read_text())
    path = d / "session.log"
    path.write_text("".join(parts))
    return path


def test_identify_accel_gives_the_clis_head_ripple_and_validation_for_the_same_session(cli, session, tmp_path):
    tomllib = pytest.importorskip("tomllib")
    out = tmp_path / "ripple.toml"
    code, stdout, err = cli("identify", "--accel", session, "--motor", REAL, "--axis", "X", "--current", "0.9",
                            "--out", out)
    assert code == 0, err
    want = tomllib.loads(out.read_text())
    got = stepdamp.identify_accel([session], Profile.load(REAL), "X", current_peak_a=0.9)
    assert got["text"] in stdout
    assert got["toml"] == out.read_text()
    assert (got["format"], got["motor"], got["axis"], got["current_peak_a"]) == ("prusa", want["motor"], "X", 0.9)
    for k in ("captures", "blocks"):
        assert got[k] == want[k]
    assert got["explained_share"] == pytest.approx(want["explained_share"], rel=1e-12)
    h, w = got["head"], want["head"]
    assert got["axis_model"]["pulley_radius_m"] == pytest.approx(w["pulley_radius_m"], rel=1e-12)
    for key, file_key in [("total_inertia_kg_m2", "total_inertia"), ("carriage_mass_kg", "carriage_mass"),
                          ("belt_hz", "belt"), ("belt_damping_ratio", "belt_damping_ratio"),
                          ("rotor_damping_nm_s_per_rad", "rotor_damping"), ("shift_delay_s", "shift_delay")]:
        unit = key[len(file_key):]
        iv = h[key]
        assert iv["value"] == pytest.approx(w[key], rel=1e-12), key
        low_high = w[f"{file_key}_95{unit}"]
        assert [iv["low"], iv["high"]] == pytest.approx(low_high, rel=1e-12), key
    assert h["belt_stiffness_n_per_m"] == pytest.approx(w["belt_stiffness_n_per_m"], rel=1e-12)
    assert (h["sensor_gain"], h["sensor_sign_fitted"]) == (w["sensor_gain"], w["sensor_sign_fitted"]) == (1.0, True)
    assert len(got["harmonics"]) == len(want["ripple"])
    for g, r in zip(got["harmonics"], want["ripple"]):
        assert (g["direction"], g["order"], g["blocks"]) == (r["direction"], r["order"], r["blocks"])
        assert g["amplitude_nm"]["value"] == pytest.approx(r["amplitude_nm"], rel=1e-12)
        assert [g["amplitude_nm"]["low"], g["amplitude_nm"]["high"]] == pytest.approx(r["amplitude_95_nm"], rel=1e-12)
        assert g["phase_rad"]["value"] == pytest.approx(r["phase_rad"], rel=1e-12)
        assert [g["phase_rad"]["low"], g["phase_rad"]["high"]] == pytest.approx(r["phase_95_rad"], rel=1e-12)
        assert g["radius95_nm"] == pytest.approx(r["radius95_nm"], rel=1e-12)
        assert list(g["speeds_rev_s"]) == pytest.approx(r["speeds_rev_s"], rel=1e-12)
        assert g["explained_share"] == pytest.approx(r["explained_share"], rel=1e-12)
    assert [(m["direction"], m["order"], m["reason"]) for m in got["not_identified"]] == [
        (m["direction"], m["order"], m["reason"]) for m in want["not_identified"]
    ]
    # The order the simulated motor has most of, within 10 % of `motor ripple --id 0.9 --iq 0`.
    four = [g for g in got["harmonics"] if g["order"] == 4]
    assert len(four) == 2 and all(abs(g["amplitude_nm"]["value"] / 0.0329 - 1) < 0.1 for g in four)
    # The same with the RMS current and a subset of orders: only those are fitted.
    rms = stepdamp.identify_accel(session, Profile.load(REAL), "x", current_rms_a=0.9 / math.sqrt(2), orders=[4, 2])
    assert rms["current_peak_a"] == pytest.approx(0.9, rel=1e-15)
    assert sorted({g["order"] for g in rms["harmonics"]}) == [2, 4]


def test_the_example_of_readme_python_runs(session, tmp_path, monkeypatch):
    shutil.copy(session, tmp_path / "session.log")
    monkeypatch.chdir(tmp_path)
    readme = (Path(__file__).resolve().parents[1] / "README-python.md").read_text()
    block = readme.split("```python\n", 1)[1].split("```", 1)[0]
    exec(compile(block.replace("docs/profiles/", f"{REAL.parent}/"), "README-python.md", "exec"), {})


def test_the_accelerometer_example_of_docs_python_runs(session, tmp_path, monkeypatch, capsys):
    doc = Path(__file__).resolve().parents[2] / "docs" / "python.md"
    section = doc.read_text().split("\n### Reading and fitting captures\n", 1)[1].split("\n### ", 1)[0]
    block = section.split("```python\n", 1)[1].split("```", 1)[0]
    shutil.copy(session, tmp_path / "session.log")
    monkeypatch.chdir(tmp_path)
    exec(compile(block.replace("docs/profiles/", f"{REAL.parent}/"), "docs/python.md", "exec"), {})
    out = capsys.readouterr().out
    # What the block's comments say it prints: the CLI's report, and the other axis refused.
    fit = stepdamp.identify_accel([session], Profile.load(REAL), "X", current_peak_a=0.9)
    assert fit["text"] in out
    assert (tmp_path / "ripple.toml").read_text() == fit["toml"]
    refused = [line for line in out.splitlines() if "moved the other axis" in line]
    assert len(refused) == 1 and refused[0] in block, refused
