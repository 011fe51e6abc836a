"""Type stubs of the Rust core of the `tilting` package (see `tilting` and `tilting.plan` for
the public API). Reports cross as the CLI's JSON text; trajectories as numpy arrays."""

from os import PathLike
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

class UsageError(ValueError):
    """Invalid input: the message names the option (as the CLI's flag) and its allowed range."""

class RunError(RuntimeError):
    """A computation that could not be done (no orbit, a failed run)."""

def simulate(argv: List[str]) -> Dict[str, object]:
    """`tilting simulate` with the flags `argv` (`--name=value`): `json` (str, the report),
    `t` (s), `x` (n x 4; rad, rad/s), `mode` (uint8: 0 flat, 1 left, 2 right), `torque` (N m)."""

def read_mcap(path: Union[str, PathLike[str]]) -> Dict[str, object]:
    """A recording: `t`, `x`, `mode`, `torque` (NaN where none answered), `events` (JSON),
    `end` (s), `stopped_early`, `robot`, `source`."""

def orbit(
    kp: float, kd: float, k: float, energy_avg: Optional[float], impact: str, params: Optional[str]
) -> str: ...
def sinusoid(
    amplitude: float,
    landing_offset: float,
    omega_min: float,
    omega_max: float,
    impact: str,
    params: Optional[str],
) -> str: ...
def bifurcation_job(
    k_from: float,
    k_to: float,
    k_step: float,
    tilts: int,
    keep: int,
    kp: float,
    kd: float,
    period_tol: float,
    impact: str,
    params: Optional[str],
) -> str: ...
def gains_job(
    kp: Sequence[float], kd: Sequence[float], impact: str, params: Optional[str]
) -> str: ...
def margins_survey(
    delays: Sequence[float],
    losses: Sequence[float],
    rate: float,
    rates: Sequence[float],
    angle_noises: Sequence[float],
    rate_noises: Sequence[float],
    mass_errors: Sequence[float],
    seed: int,
    tilts: int,
    watchdog: int,
    tolerance: float,
) -> str: ...
def margins_points(
    delay: Sequence[float],
    loss: Sequence[float],
    angle_noise: Sequence[float],
    rate_noise: Sequence[float],
    mass_error: Sequence[float],
    rate: Sequence[float],
    predict: Sequence[bool],
    seed: Sequence[int],
    tilts: int,
    watchdog: int,
    tolerance: float,
    threads: int,
) -> Tuple[List[bool], List[int], List[float], List[str]]: ...
def run_shard(kind: str, job: str, index: int, count: int) -> str:
    """Shard `index/count` of a sweep (`margins`, `bifurcation`, `gains`): its JSON."""

def run_whole(kind: str, job: str) -> str:
    """A whole sweep on all cores: the report's JSON, as the CLI's `--json`."""

def merge(kind: str, job: str, shards: List[str]) -> str:
    """The report's JSON from every shard of one split; refused unless whole."""
