"""Hostile use: sizes beyond the library's bounds, Ctrl-C during long calls, nonsense
arguments and a missing optional extra are refused with a Python exception, never an abort
or a panic (docs/python.md#errors-and-limits)."""

import gzip
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import stepdamp
from stepdamp import MAX_POINTS, StepdampError

from test_accel import M973, REAL, _klipper_log
from test_study import SPEC


def test_a_grid_larger_than_max_points_is_refused_before_allocating_naming_points_and_range():
    assert MAX_POINTS == 100_000
    for n in (10**12, MAX_POINTS + 1, -1, 2**70):
        with pytest.raises(StepdampError, match=rf"^points: {n} must be in 0\.\.=100000$"):
            stepdamp.linear_grid(1, 40, n)
    assert len(stepdamp.linear_grid(1, 40, MAX_POINTS)) == MAX_POINTS
    with pytest.raises(TypeError):
        stepdamp.linear_grid(1, 40, 4.5)


def test_a_sweep_of_more_than_max_points_speeds_is_refused_before_any_run():
    m = stepdamp.Profile.preset("patent-motor")
    with pytest.raises(StepdampError, match=r"^speeds: 100001 must be in 0\.\.=100000$"):
        stepdamp.sweep(m, "open-loop", "patent", [5.0] * (MAX_POINTS + 1))


def test_a_sweep_listing_a_mode_or_compensation_twice_is_refused_not_multiplied():
    m = stepdamp.Profile.preset("patent-motor")
    with pytest.raises(StepdampError, match=r"^modes: open-loop is listed twice$"):
        stepdamp.sweep(m, ["open-loop"] * 10**6, "patent", [5.0])
    with pytest.raises(StepdampError, match=r"^compensations: patent is listed twice$"):
        stepdamp.sweep(m, "open-loop", "off,patent,patent", [5.0])


def test_a_simulate_whose_log_would_not_fit_in_memory_is_refused_naming_the_duration_and_range():
    m = stepdamp.Profile.preset("patent-motor")
    with pytest.raises(StepdampError, match=r"^duration: 1000000 s must be in \(0, 1250\] s: at 20000 Hz .* 25000000"):
        stepdamp.simulate(m, duration_s=1e6)


def test_a_study_from_json_asking_for_more_variants_than_a_spec_may_is_refused():
    good = json.loads(stepdamp.load_spec(SPEC.format(n=3)))
    good["spec"]["variants"] = 10**15
    with pytest.raises(StepdampError, match=r"variants = 1000000000000000: must be in 1\.\.=10000000"):
        stepdamp.studies.run_chunk(json.dumps(good), 0, 0)


# The child runs a long call, prints "start" (then the parent waits ~1 s and sends SIGINT)
# and prints the time it caught KeyboardInterrupt. It restores Python's own SIGINT handler
# first: a process started in the background of a non-interactive shell (as CI may run the
# suite) inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler.
CHILD = textwrap.dedent(
    """
    import signal, sys, time
    signal.signal(signal.SIGINT, signal.default_int_handler)
    import stepdamp
    m = stepdamp.Profile.preset("patent-motor")
    SPEC = sys.argv[2]
    calls = {
        "simulate": lambda: stepdamp.simulate(m, "open-loop", "patent", 10.0, 1000.0),
        "sweep": lambda: stepdamp.sweep(m, "open-loop", "patent", [5.0, 10.0], duration_s=1000.0),
        "study": lambda: stepdamp.study(SPEC, dask=False),
    }
    print("start", flush=True)
    try:
        calls[sys.argv[1]]()
    except KeyboardInterrupt:
        print("KeyboardInterrupt", time.monotonic(), flush=True)
        sys.exit(0)
    print("finished", flush=True)
    """
)

LONG_STUDY = SPEC.format(n=400).replace("duration_s = 0.4", "duration_s = 100.0")


@pytest.mark.parametrize("call", ["simulate", "sweep", "study"])
def test_ctrl_c_during_a_long_call_raises_keyboard_interrupt_within_half_a_second(call):
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, call, LONG_STUDY],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert child.stdout.readline().strip() == "start"
        time.sleep(1.0)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()
    assert "PanicException" not in err, err
    lines = out.split()
    assert lines[:1] == ["KeyboardInterrupt"], (out, err)
    assert child.returncode == 0, err
    assert float(lines[1]) - sent <= 0.5, f"KeyboardInterrupt {float(lines[1]) - sent:.3f} s after SIGINT"


def test_non_integral_orders_are_refused_naming_the_value_not_truncated():
    base = stepdamp.Profile.preset("patent-motor")
    with pytest.raises(StepdampError, match=r"orders: 4\.5 is not an integer"):
        stepdamp.identify([], base, orders=[4.5])
    with pytest.raises(StepdampError, match=r"orders: 'x' is not an integer"):
        stepdamp.identify([], base, orders=["x"])
    assert stepdamp._orders([4, 2.0, 1]) == [4, 2, 1]


def test_study_without_the_study_extra_names_the_extra_and_the_pip_command(monkeypatch):
    # What `pip install stepdamp` without [study] looks like: dask cannot be imported.
    monkeypatch.setitem(sys.modules, "dask", None)
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(ModuleNotFoundError, match=r"\[study\] extra \(dask\.distributed is missing\): "
                       r"pip install 'stepdamp\[study\]'"):
        stepdamp.study(SPEC.format(n=2))


def test_the_documented_study_snippets_guard_the_cluster_start_with_if_main():
    root = os.path.join(os.path.dirname(__file__), "..", "..")
    for doc in ("README.md", os.path.join("docs", "python.md")):
        path = os.path.join(root, doc)
        if not os.path.exists(path):
            pytest.skip("run from a source tree")
        text = open(path, encoding="utf-8").read()
        blocks = text.split("```python")[1:]
        for b in (b.split("```")[0] for b in blocks):
            starts = [line for line in b.splitlines() if "stepdamp.study(" in line and "dask=False" not in line]
            if starts:
                assert 'if __name__ == "__main__":' in b, f"{doc}: unguarded study snippet:\n{b}"


def _servo_frames():
    p = stepdamp.Profile.preset("patent-motor")
    return p, [stepdamp.simulate(p, "servo", "off", w, 1.2, current_noise_a=0.005, seed=i)
               for i, w in enumerate([6.0, 11.0, -6.0, -11.0])]


def test_dataframes_reach_rust_as_views_of_their_arrays_not_as_csv_text(monkeypatch):
    import pandas as pd

    from stepdamp import _log_arg

    p, logs = _servo_frames()
    name, values, unused = _log_arg(logs[0], 0)
    assert name == "<DataFrame 0>" and set(unused) <= set(logs[0].columns) - set(stepdamp._native.LOG_COLUMNS)
    for column, array in values:
        assert np.shares_memory(array, logs[0][column].to_numpy()), column

    def no_csv(*a, **k):
        raise AssertionError("identify wrote a DataFrame as CSV text")

    monkeypatch.setattr(pd.DataFrame, "to_csv", no_csv)
    base = p.copy()
    base.detent = []
    found, report = stepdamp.identify(logs, base, orders=[1, 2, 4])
    a4 = [h for h in found.detent if h["order"] == 4][0]["amplitude_nm"]
    assert abs(a4 - 0.02) < 0.002, report


def test_a_bad_value_in_a_dataframe_is_refused_naming_frame_line_and_column():
    p, logs = _servo_frames()
    bad = logs[1].copy()
    bad.loc[5, "i_q_a"] = float("nan")
    with pytest.raises(StepdampError, match=r"^<DataFrame 1>: line 7, column 'i_q_a': \"NaN\" is not a finite number$"):
        stepdamp.identify([logs[0], bad], p)
    text = logs[0].astype({"i_q_a": object})
    text.loc[3, "i_q_a"] = "1,5"
    with pytest.raises(StepdampError, match=r"^<DataFrame 0>: line 5, column 'i_q_a': '1,5' is not a number$"):
        stepdamp.identify([text], p)
    twice = pd_concat_columns(logs[0])
    with pytest.raises(StepdampError, match=r"column 't_s' appears twice"):
        stepdamp.identify([twice], p)
    with pytest.raises(StepdampError, match=r"^<log 0>: column 'i_q_a' has 3 rows, column 't_s' has 2"):
        stepdamp.identify([{"t_s": [0.0, 1.0], "theta_fb_rad": [0.0, 1.0], "i_q_a": [0.0, 1.0, 2.0]}], p)


def pd_concat_columns(frame):
    """``frame`` with its ``t_s`` column twice (a DataFrame allows that, a log does not)."""
    import pandas as pd

    return pd.concat([frame, frame[["t_s"]]], axis=1)


# The accelerometer route (docs/python.md#reading-and-fitting-captures): whatever the file, the
# axis or the trial, a StepdampError with one printable line naming what was wrong.
CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def _refused(call, *args, match, **kwargs):
    """Asserts that ``call`` raises StepdampError whose message matches ``match``, is one
    line and holds no control character (an escape sequence would reach the terminal)."""
    with pytest.raises(StepdampError) as e:
        call(*args, **kwargs)
    msg = str(e.value)
    assert not CONTROL.search(msg), repr(msg)
    assert re.search(match, msg), msg
    return msg


def _both(path, match, **kwargs):
    """`read_accel_captures(path)` and `identify_accel([path], …)` both refuse ``path``."""
    motor = stepdamp.Profile.load(REAL)
    _refused(stepdamp.read_accel_captures, path, match=match, **kwargs)
    _refused(stepdamp.identify_accel, [path], motor, "X", current_peak_a=0.9, match=match)


def _gzip(path, payload):
    with gzip.open(path, "wb") as f:
        f.write(payload)
    return path


def test_accel_files_that_are_not_captures_are_refused_naming_the_file_on_one_line(tmp_path):
    empty = tmp_path / "empty.txt"
    empty.write_bytes(b"")
    _both(empty, rf"^{re.escape(str(empty))}: no M973/M974 capture")
    garbage = tmp_path / "garbage.bin"
    garbage.write_bytes(bytes(range(256)) * 3 + b"\x1b[2J\n")
    _both(garbage, rf"^{re.escape(str(garbage))}:\d+: `.*`: expected UTF-8 text")
    huge = tmp_path / "huge.txt"
    huge.write_bytes(b"0, " + b"1" * 50_000_000)
    _both(huge, rf"^{re.escape(str(huge))}:1: longer than 1024 bytes")
    folder = tmp_path / "captures"
    folder.mkdir()
    _both(folder, rf"^{re.escape(str(folder))}: cannot read: Is a directory")
    missing = tmp_path / "missing.txt"
    _both(missing, rf"^{re.escape(str(missing))}: cannot read: No such file or directory")
    # A name with a newline and an escape sequence is quoted escaped, as every file name is.
    odd = tmp_path / "a\nb\x1b[31m.txt"
    _both(odd, r"a\\u\{a\}b\\u\{1b\}\[31m\.txt: cannot read: No such file")


def test_accel_gzip_files_that_are_not_klipper_logs_are_refused_naming_the_file_on_one_line(tmp_path):
    text = _gzip(tmp_path / "text.gz", b"hello\n\x1b[31m world\n")
    _both(text, r"text\.gz: record 1: \(framing\) = hello\\u\{a\}\\u\{1b\}\[31m world")
    noise = _gzip(tmp_path / "noise.gz", bytes(range(256)) * 40 + b"\x03")
    _both(noise, r"noise\.gz: .*(stepq:stepper_x|configfile|accelerometer)")
    cut = tmp_path / "cut.gz"
    _klipper_log(cut)
    cut.write_bytes(cut.read_bytes()[:-20])
    _both(cut, r"cut\.gz: after \d+ decompressed bytes: the gzip stream is cut")
    huge = _gzip(tmp_path / "huge.gz", b"[" + b"1," * 40_000_000 + b"1]\x03")
    _both(huge, r"huge\.gz: record 1: more than \d+ bytes in one message")


def test_a_klipper_log_with_nan_samples_is_refused_not_fitted_into_nan(tmp_path):
    log = tmp_path / "LOG.json.gz"
    _klipper_log(log)
    with gzip.open(log, "rb") as f:
        records = f.read().split(b"\x03")
    i = next(i for i, r in enumerate(records) if b"accelerometer:adxl345" in r)
    records[i] = records[i].replace(b"5.0, 9810.0]", b"NaN, 9810.0]", 1)
    _gzip(log, b"\x03".join(records))
    _both(log, r"LOG\.json\.gz: record \d+: ")


@pytest.mark.parametrize("trial", [(4, float("nan"), 0.0), (4, 0.1, float("inf")), (4, float("-inf"), 0.0),
                                   (0, 0.1, 0.0), (17, 0.1, 0.0), (4, 2.0, 0.0)])
def test_a_klipper_trial_out_of_range_or_not_finite_is_refused_naming_the_log_and_range(tmp_path, trial):
    log = tmp_path / "LOG.json.gz"
    _klipper_log(log)
    ranges = r"harmonic 1\.\.=16, amplitude 0\.\.=1 rad, a finite phase"
    _refused(stepdamp.read_accel_captures, log, trial=trial, match=rf"LOG\.json\.gz: trial \(H, U, PHI\) = \(\d+, \S+, \S+\): {ranges}$")
    _refused(stepdamp.identify_accel, [log], stepdamp.Profile.load(REAL), "X", current_peak_a=0.9,
             klipper_trials={log: trial}, match=rf"LOG\.json\.gz: trial \(H, U, PHI\) = \(\d+, \S+, \S+\): {ranges}$")


def test_accel_arguments_out_of_range_are_refused_on_one_line():
    motor = stepdamp.Profile.load(REAL)
    for axis in ("Z", "", "\x1b[31mX", "X\n"):
        _refused(stepdamp.read_accel_captures, M973, axis=axis, match=r'^axis ".*": Prusa phase stepping has axes X and Y$')
        _refused(stepdamp.identify_accel, [M973], motor, axis, current_peak_a=0.9, match=r'^axis ".*": ')
    for mm in (float("nan"), float("inf"), 0.0, -32.0):
        _refused(stepdamp.read_accel_captures, M973, mm_per_rev=mm, match=r"mm_per_rev")
        _refused(stepdamp.identify_accel, [M973], motor, "X", current_peak_a=0.9, mm_per_rev=mm,
                 match=r"^mm_per_rev \S+: must be in 6\.3\.\.=314 mm")
    for current in (float("nan"), float("inf"), 0.0, -1.0):
        _refused(stepdamp.identify_accel, [M973], motor, "X", current_peak_a=current,
                 match=r"^current_peak_a \S+: must be finite and > 0 A$")
        _refused(stepdamp.identify_accel, [M973], motor, "X", current_rms_a=current,
                 match=r"^current_rms_a \S+: must be finite and > 0 A$")
    _refused(stepdamp.identify_accel, [], motor, "X", current_peak_a=0.9, match=r"^paths: no capture given$")
    _refused(stepdamp.identify_accel, [M973], motor, "X", current_peak_a=0.9, periods_per_block=0,
             match=r"periods_per_block|block")
    _refused(stepdamp.read_accel_captures, M973, periods_per_rev=0, match=r"periods_per_rev")
