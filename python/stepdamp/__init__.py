"""stepdamp: model-based active damping of hybrid stepper motors (Rust core).

Units are SI and in the names: ``speed_rad_s``, ``duration_s``, ``load_torque_nm`` …

>>> import stepdamp
>>> motor = stepdamp.Profile.preset("patent-motor")
>>> log = stepdamp.simulate(motor, "open-loop", "patent", speed_rad_s=8.4, duration_s=0.4)

Every number comes from the Rust crates (the same code as the ``stepdamp`` CLI); errors are
raised as :class:`StepdampError` (a ``ValueError``) with the CLI's one-line message.
"""

from __future__ import annotations

import json
import math
import operator
import os
from typing import Any, Iterable, Sequence, Union

import numpy as np

from . import _native
from ._native import (
    MAX_POINTS,
    PRESETS,
    Profile,
    StepdampError,
    identify_accel,
    klipper_plan,
    klipper_refine,
    klipper_trial_table,
    prusa_refine,
    read_accel_captures,
)

__all__ = [
    "MAX_POINTS",
    "PRESETS",
    "Profile",
    "StepdampError",
    "StudyResult",
    "SweepSummary",
    "identify",
    "identify_accel",
    "klipper_plan",
    "klipper_refine",
    "klipper_trial_table",
    "linear_grid",
    "load_spec",
    "prusa_refine",
    "read_accel_captures",
    "resonance",
    "ripple",
    "simulate",
    "study",
    "sweep",
]

try:  # pandas is optional: without it the tables come back as dicts of numpy arrays.
    import pandas as _pd
except ImportError:  # pragma: no cover - exercised on machines without pandas
    _pd = None


def _table(columns: dict, as_frame: Union[bool, None]):
    if as_frame is None:
        as_frame = _pd is not None
    if as_frame:
        if _pd is None:
            raise ImportError("as_frame=True needs pandas (pip install pandas)")
        return _pd.DataFrame(columns, copy=False)
    return columns


def simulate(
    profile: Profile,
    mode: str = "open-loop",
    compensation: str = "patent",
    speed_rad_s: float = 10.0,
    duration_s: float = _native.DURATION_S,
    *,
    controller: Union[Profile, None] = None,
    dwell_s: float = _native.DWELL_S,
    ramp_s: float = _native.RAMP_S,
    load_torque_nm: float = 0.0,
    current_noise_a: float = 0.0,
    substeps: Union[int, None] = None,
    seed: int = 1,
    as_frame: Union[bool, None] = None,
    return_metrics: bool = False,
):
    """One constant-speed run from rest (the CLI's ``stepdamp simulate``).

    ``mode``: ``open-loop`` or ``servo``; ``compensation``: ``off``, ``patent``,
    ``estimated`` or ``angle`` (these two in open loop only; ``table`` replays a table file,
    which only the CLI's ``sweep --table`` takes). The run holds the motor at standstill for ``dwell_s``,
    ramps to ``speed_rad_s`` (rad/s) in ``ramp_s`` and runs to ``duration_s`` (s).
    ``controller`` is the profile the controller believes in (default: ``profile``).
    ``substeps``: RK4 steps of the plant per PWM period (``None``: the library's default,
    as the CLI's).

    Returns the run log, one row per control period, columns ``t_s``, ``theta_cmd_rad``,
    ``theta_fb_rad``, ``omega_fb_rad_s``, ``i_a_a``, ``i_b_a``, ``i_d_a``, ``i_q_a``,
    ``iq_cmd_a``, ``v_a_v``, ``v_b_v`` (the mean winding voltages applied over each period,
    V; what the sensorless route integrates): a pandas DataFrame when pandas is installed (``as_frame=None``), else a
    dict of numpy arrays. With ``return_metrics=True``, ``(log, metrics)`` where metrics
    has ``vel_err_rms_rad_s``, ``vel_err_pp_rad_s``, ``lost_sync``,
    ``max_load_angle_e_rad``.
    """
    log, metrics = _native.simulate(
        profile, mode, compensation, float(speed_rad_s), float(duration_s),
        controller=controller, dwell_s=dwell_s, ramp_s=ramp_s, load_torque_nm=load_torque_nm,
        current_noise_a=current_noise_a, substeps=substeps, seed=seed,
    )
    out = _table(log, as_frame)
    if return_metrics:
        return out, metrics
    return out


def linear_grid(from_rad_s: float, to_rad_s: float, points: int) -> list:
    """``points`` speeds evenly spaced from ``from_rad_s`` to ``to_rad_s`` inclusive, rad/s
    (the CLI's ``--from/--to/--points`` grid, bit for bit). ``points`` is an integer in
    ``0..=MAX_POINTS`` (100 000, the library's bound); more raises :class:`StepdampError`
    before anything is allocated."""
    n = operator.index(points)
    if not 0 <= n < 2**64:
        # The library's check says the same for a count it can take (a u64).
        raise StepdampError(f"points: {n} must be in 0..={MAX_POINTS}")
    return _native.linear_grid(float(from_rad_s), float(to_rad_s), n)


class SweepSummary(dict):
    """The summary of a sweep, the library's ``SweepSummary`` (the CLI's ``sweep --format
    json``, key for key): ``motor``, ``natural_frequency_rad_s`` (rad/s), ``damping_ratio``,
    ``resonances`` (``[{order, speed_rad_s}]``, rad/s, highest order first), ``from_rad_s``,
    ``to_rad_s`` and ``modes``: per mode ``{mode, compensations, near_resonances}``, where
    ``compensations`` gives per compensation the median RMS and worst peak-to-peak velocity error (rad/s) and
    their ratios to compensation off (``vs_off``: off / this, how many times less), and
    ``near_resonances`` the highest peak-to-peak error within ±10 % of each resonance speed
    per compensation (``peaks``: ``[{compensation, pp_rad_s, vs_off}]``). A diverged run's
    infinite error is ``None`` (JSON has no infinity). ``str()`` is the CLI's printed text."""

    def __init__(self, data: dict, text: str = ""):
        super().__init__(data)
        self._text = text

    def __str__(self) -> str:
        return self._text

    def __repr__(self) -> str:
        return f"SweepSummary(\n{self._text})"


def _list(x: Union[str, Iterable[str]]) -> list:
    if isinstance(x, str):
        return [p.strip() for p in x.split(",")]
    return list(x)


def sweep(
    profile: Profile,
    modes: Union[str, Sequence[str]] = ("open-loop", "servo"),
    compensations: Union[str, Sequence[str]] = ("off", "patent"),
    speeds_rad_s: Union[Sequence[float], np.ndarray, None] = None,
    *,
    controller: Union[Profile, None] = None,
    duration_s: float = _native.DURATION_S,
    load_torque_nm: float = 0.0,
    current_noise_a: float = 0.0,
    substeps: Union[int, None] = None,
    seed: int = 1,
    as_frame: Union[bool, None] = None,
):
    """Velocity error against speed (the CLI's ``stepdamp sweep``), on all cores.

    ``modes``: ``open-loop``, ``servo``; ``compensations``: ``off``, ``patent``,
    ``estimated``, ``angle`` (a list or a comma-separated string; ``table`` needs the CLI's
    ``--table`` file). ``speeds_rad_s`` defaults to the CLI's grid, ``linear_grid(1, 40,
    60)``. ``substeps``: RK4 steps per PWM period (``None``: the library's default, as the
    CLI's). Returns
    ``(table, summary)``: the sweep table (columns ``mode``, ``compensation``,
    ``speed_cmd_rad_s``, ``vel_err_rms_rad_s``, ``vel_err_pp_rad_s``, ``lost_sync``; the CLI's
    ``sweep.csv``) and a :class:`SweepSummary`.
    """
    if speeds_rad_s is None:
        speeds_rad_s = linear_grid(1.0, 40.0, 60)
    table, summary_json, summary_text = _native.sweep(
        profile, _list(modes), _list(compensations), [float(w) for w in np.asarray(speeds_rad_s).ravel()],
        controller=controller, duration_s=duration_s, load_torque_nm=load_torque_nm,
        current_noise_a=current_noise_a, substeps=substeps, seed=seed,
    )
    return _table(table, as_frame), SweepSummary(json.loads(summary_json), summary_text)


def _log_arg(log: Any, i: int):
    """A path as it is, or a frame as ``(name, [(column, float64 array)], [other names])``:
    the run-log columns go to Rust as arrays (views where they already are contiguous
    float64, no CSV text), any other column by name only (reported as ignored)."""
    if isinstance(log, (str, os.PathLike)):
        return log
    if _pd is not None and isinstance(log, _pd.DataFrame):
        name, items = f"<DataFrame {i}>", [(c, log.iloc[:, j]) for j, c in enumerate(log.columns)]
    elif isinstance(log, dict):
        name, items = f"<log {i}>", list(log.items())
    else:
        raise TypeError(f"log {i}: expected a path, a pandas DataFrame or a dict of arrays, got {type(log).__name__}")
    known = set(_native.LOG_COLUMNS)
    values, unused = [], []
    for column, data in items:
        if isinstance(column, str) and column in known:
            values.append((column, _float_column(name, column, data)))
        else:
            unused.append(str(column))
    return (name, values, unused)


def _float_column(name: str, column: str, data: Any) -> np.ndarray:
    """``data`` as a contiguous 1-D float64 array (a view when it already is one); a value
    that is not a number is refused naming its line as in the CSV the frame would write."""
    try:
        array = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is not None:
        if array.ndim != 1:
            raise StepdampError(f"{name}: column '{column}' has shape {array.shape}: expected one value per row")
        return np.ascontiguousarray(array)
    for j, v in enumerate(np.asarray(data, dtype=object).reshape(-1)):
        try:
            float(v)
        except (TypeError, ValueError):
            raise StepdampError(f"{name}: line {j + 2}, column '{column}': {str(v)[:40]!r} is not a number") from None
    raise StepdampError(f"{name}: column '{column}' cannot be read as float64 numbers")


def identify(
    logs: Sequence[Any],
    base: Profile,
    orders: Sequence[int] = (1, 2, 4),
    name: Union[str, None] = None,
    sensorless: Union[bool, None] = None,
):
    """Identifies the detent harmonics, Coulomb and viscous friction and the inertia from
    run logs (the CLI's ``stepdamp identify``).

    ``logs``: paths of run-log CSV files, pandas DataFrames or dicts of arrays with the
    run-log columns: servo logs ``t_s``, ``theta_fb_rad``, ``i_q_a`` or ``i_a_a``/``i_b_a``
    (optionally ``iq_cmd_a``); or, for the sensorless route (docs/sensorless.md), open-loop
    logs ``t_s``, ``theta_cmd_rad``, ``i_a_a``, ``i_b_a``, ``v_a_v``, ``v_b_v`` of the runs
    the CLI's ``identify plan --sensorless`` lists. ``base``: the profile whose Km, Nr,
    encoder and servo settings (sensorless: Km, Nr, R, L) apply. ``sensorless``: ``None``
    takes the sensorless route when the logs have no ``theta_fb_rad`` (a set of both kinds
    is refused; a file given twice too); ``True`` or ``False`` forces a route. Returns ``(profile, report)``: ``base`` with the identified
    values (named ``name``; sensorless: ``R`` trimmed too) and the fit report (estimates with
    95 % half-widths, N·m, rad, kg·m²; warnings; ``route``; sensorless: ``resistance_ohm``
    in Ω and ``current_offset_a``, the sampled currents' offset in A).
    """
    args = [_log_arg(log, i) for i, log in enumerate(logs)]
    return _native.identify(args, base, _orders(orders), name, sensorless)


def _orders(orders: Sequence[Any]) -> list:
    """The harmonic orders as integers; a non-integral one (``4.5``) is refused, not truncated."""
    out = []
    for k in orders:
        try:
            out.append(operator.index(k))
            continue
        except TypeError:
            pass
        try:
            f = float(k)
        except (TypeError, ValueError):
            f = math.nan
        if not f.is_integer():
            raise StepdampError(f"orders: {k!r} is not an integer (a harmonic order per electrical period, e.g. 4)")
        out.append(int(f))
    return out


def ripple(profile: Profile, i_d_a: float, i_q_a: float) -> dict:
    """The total ripple torque of ``profile`` at rotor-frame currents ``i_d_a``, ``i_q_a`` (A),
    as the CLI's ``motor ripple --format json``: ``harmonics`` (detent plus the ripple that
    grows with current), ``detent`` and ``current`` apart, each a list of
    ``{"order", "amplitude_nm", "phase_rad"}`` in the convention torque on the rotor
    ``-A·sin(k·θe + φ)``, and ``mean_torque_nm``. Open loop at the holding current is
    ``ripple(p, p.holding_current_a, 0.0)``; a servo at ``i_d = 0`` is ``ripple(p, 0.0, i_q)``."""
    return json.loads(profile.ripple_json(float(i_d_a), float(i_q_a)))


def resonance(profile: Profile) -> dict:
    """Natural frequency (rad/s), holding stiffness (N·m/rad), damping ratio and the
    resonance speed of each detent order, highest first (4, 2, 1 when the profile has no
    detent), rad/s, of a profile (the CLI's ``resonance``)."""
    return _native.resonance(profile)


from .studies import StudyResult, load_spec, study  # noqa: E402
