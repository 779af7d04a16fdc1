"""Type stubs of the Rust extension (stepdamp._native). Units are SI and in the names."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

DURATION_S: float
"""Default run duration, s (stepdamp_sim::RunSpec::DURATION_S)."""
DWELL_S: float
"""Default standstill before the ramp, s."""
RAMP_S: float
"""Default ramp from rest, s."""
MAX_POINTS: int
"""Most points of a speed grid and speeds of a sweep (stepdamp_sim::MAX_POINTS)."""
PRESETS: List[str]

class StepdampError(ValueError):
    """An error reported by stepdamp's Rust code (the CLI's one-line message)."""

class Profile:
    """A motor profile (the CLI's TOML format); setting an attribute validates it."""

    name: str
    km_nm_per_a: float
    """Torque constant Km, N·m/A."""
    pole_pairs: int
    """Rotor teeth / pole pairs Nr."""
    resistance_ohm: float
    """Phase resistance R, Ω."""
    inductance_h: float
    """Phase inductance L, H."""
    inertia_kg_m2: float
    """Rotor + load inertia J, kg·m²."""
    viscous_nm_s_per_rad: float
    """Viscous friction D, N·m·s/rad."""
    coulomb_friction_nm: float
    """Coulomb friction Fs, N·m."""
    bus_voltage_v: float
    """DC bus voltage, V."""
    pwm_hz: float
    """PWM and control frequency, Hz."""
    holding_current_a: float
    """Open-loop holding current, A."""
    current_limit_a: float
    """Current vector limit, A."""
    current_loop_bandwidth_hz: float
    """Closed current-loop bandwidth, Hz."""
    computation_delay_periods: int
    """Periods between sampling and the new duties taking effect (0 or 1)."""
    counts_per_rev: int
    """Encoder counts per mechanical revolution."""
    servo_bandwidth_hz: float
    """Servo position-loop natural frequency, Hz."""
    servo_velocity_filter_hz: float
    """Encoder velocity filter corner, Hz."""
    topology: str
    """Power stage: "three-leg" or "two-h-bridge"."""
    detent: List[Dict[str, Any]]
    """Detent harmonics {order, amplitude_nm (N·m), phase_rad (rad)}; torque −Σ A sin(k·Nr·θ + φ)."""

    @staticmethod
    def preset(name: str) -> Profile: ...
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> Profile:
        """A TOML file (a name with "/" or ending in ".toml") or a preset name, as the CLI's --motor."""
        ...
    @staticmethod
    def from_toml(text: str, origin: str = "<string>") -> Profile: ...
    def to_toml(self) -> str: ...
    def holding_stiffness_nm_per_rad(self) -> float: ...
    def natural_frequency_rad_s(self) -> float: ...
    def resonance_speed_rad_s(self, order: int) -> float: ...
    def ripple_json(self, i_d_a: float, i_q_a: float) -> str: ...
    def damping_ratio(self) -> float: ...
    def copy(self) -> Profile: ...

def simulate(
    profile: Profile,
    mode: str = "open-loop",
    compensation: str = "patent",
    speed_rad_s: float = 10.0,
    duration_s: float = ...,
    *,
    controller: Optional[Profile] = None,
    dwell_s: float = ...,
    ramp_s: float = ...,
    load_torque_nm: float = 0.0,
    current_noise_a: float = 0.0,
    substeps: Optional[int] = None,
    seed: int = 1,
) -> Tuple[Dict[str, npt.NDArray[np.float64]], Dict[str, Any]]: ...
def linear_grid(from_rad_s: float, to_rad_s: float, points: int) -> List[float]: ...
def sweep(
    profile: Profile,
    modes: Sequence[str],
    compensations: Sequence[str],
    speeds_rad_s: Sequence[float],
    *,
    controller: Optional[Profile] = None,
    duration_s: float = ...,
    load_torque_nm: float = 0.0,
    current_noise_a: float = 0.0,
    substeps: Optional[int] = None,
    seed: int = 1,
) -> Tuple[Dict[str, Any], str, str]:
    """(table columns, SweepSummary as JSON, SweepSummary as the CLI's text)."""
    ...
def resonance(profile: Profile) -> Dict[str, Any]: ...
def identify(
    logs: Sequence[Union[str, PathLike[str], Tuple[str, List[Tuple[str, npt.NDArray[np.float64]]], List[str]]]],
    base: Profile,
    orders: Sequence[int] = ...,
    name: Optional[str] = None,
    sensorless: Optional[bool] = None,
) -> Tuple[Profile, Dict[str, Any]]: ...
def read_accel_captures(
    path: Union[str, PathLike[str]],
    *,
    axis: str = "X",
    periods_per_rev: int = 50,
    mm_per_rev: float = 32.0,
    trial: Optional[Tuple[int, float, float]] = None,
) -> List[Dict[str, Any]]:
    """Prusa M973/M974 captures or a Klipper log's stretches: arrays t_s (s), accel_m_s2 (m/s²),
    theta_e_rad (rad, commanded electrical angle), speed_rev_s, accel_rev_s2, motor_rev; format,
    direction, sampling_freq_hz (Hz) and, for Prusa, the annotations."""
    ...
def identify_accel(
    paths: Union[str, PathLike[str], Sequence[Union[str, PathLike[str]]]],
    motor: Profile,
    axis: str,
    *,
    current_peak_a: Optional[float] = None,
    current_rms_a: Optional[float] = None,
    mm_per_rev: float = 32.0,
    periods_per_block: int = 4,
    klipper_trials: Optional[Dict[Union[str, PathLike[str]], Tuple[int, float, float]]] = None,
    orders: Optional[Sequence[int]] = None,
) -> Dict[str, Any]:
    """The head and the ripple per direction with 95 % intervals and the validation (the
    library's RippleFit as a dict), as the CLI's identify --accel; "text" is the report it
    prints and "toml" the file it writes (docs/files.md#identified-ripple-toml)."""
    ...
def klipper_plan(
    axis: str,
    kinematics: str,
    rotation_distance: float,
    *,
    travel_mm: float = 100.0,
    speed_rev_s: float = 2.0,
    accel_mm_s2: float = 1000.0,
    steady_s: float = 3.0,
) -> Dict[str, Any]:
    """The moves to log for the Trinamic table step ("moves", each dx_mm, dy_mm, feed_mm_min,
    motor_revs, kept_s) and "gcode", the text the CLI's accel klipper-plan prints."""
    ...
def klipper_trial_table(axis: str, *, harmonic: int = 4, shift_rad: float = 0.12) -> Dict[str, Any]:
    """The trial table of the CLI's accel klipper-trial: harmonic, shift_rad, achieved_rad,
    stray_rad, "klipper_trial" (the trial argument, e.g. "4,0.1201,0") and "block" (the file)."""
    ...
def klipper_refine(
    paths: Union[str, PathLike[str], Sequence[Union[str, PathLike[str]]]],
    motor: Profile,
    axis: str,
    *,
    klipper_trials: Dict[Union[str, PathLike[str]], Tuple[int, float, float]],
    in_use: Optional[Union[str, PathLike[str]]] = None,
    periods_per_block: int = 20,
) -> Dict[str, Any]:
    """One influence step on a Trinamic table from Klipper logs, as the CLI's accel
    klipper-refine: the shifts (rad), "pairs", "table", "text" (the report) and "block" (the file)."""
    ...
def prusa_refine(
    paths: Union[str, PathLike[str], Sequence[Union[str, PathLike[str]]]],
    motor: Profile,
    axis: str,
    *,
    current_peak_a: Optional[float] = None,
    current_rms_a: Optional[float] = None,
    in_use: Optional[Union[str, PathLike[str]]] = None,
    influence_from: Optional[Union[str, PathLike[str], Sequence[Union[str, PathLike[str]]]]] = None,
    influence_current_peak_a: Optional[float] = None,
    influence_current_rms_a: Optional[float] = None,
    mm_per_rev: float = 32.0,
    periods_per_block: int = 20,
    timing: str = "planned",
) -> Dict[str, Any]:
    """One influence step on Prusa's M971 table from M973 captures, as the CLI's accel refine:
    "steps" (per harmonic and direction), "text" (the report) and "gcode" (the file)."""
    ...
def study_load(path: Union[str, PathLike[str]]) -> str: ...
def study_from_toml(text: str, origin: str = "<string>", base_dir: str = ".") -> str: ...
def study_info(json: str) -> Tuple[int, List[str]]: ...
def study_run_range(json: str, start: int, stop: int) -> Dict[str, npt.NDArray[np.float64]]: ...
def study_summarize(json: str, columns: Dict[str, Sequence[float]]) -> Tuple[str, str]: ...
