from os import PathLike
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from ._native import MAX_POINTS as MAX_POINTS, PRESETS as PRESETS, Profile as Profile, StepdampError as StepdampError
from ._native import identify_accel as identify_accel, read_accel_captures as read_accel_captures
from ._native import prusa_refine as prusa_refine
from .studies import StudyResult as StudyResult, load_spec as load_spec, study as study

class SweepSummary(Dict[str, Any]):
    """The library's sweep summary (the CLI's ``sweep --format json``); ``str()`` is the CLI's text."""

    def __init__(self, data: Dict[str, Any], text: str = ...) -> None: ...

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
    as_frame: Optional[bool] = None,
    return_metrics: bool = False,
) -> Any: ...
def linear_grid(from_rad_s: float, to_rad_s: float, points: int) -> list: ...
def sweep(
    profile: Profile,
    modes: Union[str, Sequence[str]] = ...,
    compensations: Union[str, Sequence[str]] = ...,
    speeds_rad_s: Union[Sequence[float], np.ndarray, None] = None,
    *,
    controller: Optional[Profile] = None,
    duration_s: float = ...,
    load_torque_nm: float = 0.0,
    current_noise_a: float = 0.0,
    substeps: Optional[int] = None,
    seed: int = 1,
    as_frame: Optional[bool] = None,
) -> Tuple[Any, SweepSummary]: ...
def identify(
    logs: Sequence[Any],
    base: Profile,
    orders: Sequence[int] = (1, 2, 4),
    name: Optional[str] = None,
    sensorless: Optional[bool] = None,
) -> Tuple[Profile, Dict[str, Any]]: ...
def ripple(profile: Profile, i_d_a: float, i_q_a: float) -> Dict[str, Any]: ...
def resonance(profile: Profile) -> Dict[str, Any]: ...
