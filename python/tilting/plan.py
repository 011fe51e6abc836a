"""The planner (``tilting plan ...``) from Python: the paper's boundary value problems and
sweeps, returning typed results (numpy where a table is natural).

Every function takes the CLI's options as keyword arguments with the CLI's defaults (``-``
written ``_``), checks them with the CLI's code (a bad value raises
:class:`tilting.UsageError` with the CLI's message) and releases the GIL while it computes.
``bifurcation``, ``gains`` and ``margins`` take a Dask ``client``: the sweep then runs as
shards, one task each, merged as ``tilting plan merge`` does; the result is the same bit for
bit, with or without a client, however many ``partitions``. Each result keeps the CLI's JSON
report in ``report`` (a dict), equal to what ``tilting plan ... --json`` prints.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import _core
from ._core import UsageError
from ._sweep import run_sharded

__all__ = [
    "orbit",
    "sinusoid",
    "bifurcation",
    "gains",
    "margins",
    "margins_point",
    "Orbit",
    "OrbitResult",
    "SinusoidResult",
    "BifurcationResult",
    "GainsResult",
    "MarginsResult",
    "MarginsPoint",
]

# The paper's gains (Sec. III-B, the CLI's defaults): K_P = 100 1/s^2, K_D = 14.14 1/s.
_KP, _KD = 100.0, 14.14


def _path(name: str, p: Any) -> Optional[str]:
    if p is None:
        return None
    if not isinstance(p, (str, os.PathLike)):
        raise TypeError(f"`{name}` must be a path to a TOML file, not {type(p).__name__}")
    return os.fspath(p)


def _floats(name: str, v: Any) -> List[float]:
    if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
        raise TypeError(f"`{name}` must be a list of numbers, not {type(v).__name__}")
    out = []
    for e in v:
        if isinstance(e, bool) or not isinstance(e, (int, float, np.integer, np.floating)):
            raise TypeError(f"`{name}` must be a list of numbers, not one holding {type(e).__name__}")
        out.append(float(e))
    return out


@dataclass
class Orbit:
    """A periodic orbit of approach 2 (one left tilt and its mirror image)."""

    beta0: float  #: beta(0) - pi/2 at the start of the left tilt (rad)
    beta_dot0: float  #: beta_dot(0) (rad/s)
    t_end: float  #: duration of the left tilt (s)
    period: float  #: period of the orbit (s)
    max_tilt: float  #: maximal |alpha| (rad)
    energy_avg: float  #: mean energy over the orbit (J)
    multipliers: np.ndarray  #: Floquet multipliers, shape (m, 2): real and imaginary parts
    stable: bool  #: all multipliers inside the unit circle
    raw: Dict[str, Any]  #: the orbit's JSON object


@dataclass
class OrbitResult:
    """``tilting plan orbit``: the orbits for one gain pair, by increasing maximal tilt."""

    kp: float  #: K_P (1/s^2)
    kd: float  #: K_D (1/s)
    k: float  #: adaptation gain k (1/(J s^2))
    energy_avg_adaptation: Optional[float]  #: E_av of the adaptation (J), with k > 0
    solutions: List[Orbit]
    report: Dict[str, Any]


def orbit(
    kp: float = _KP,
    kd: float = _KD,
    k: float = 0.0,
    energy_avg: Optional[float] = None,
    impact: str = "paper",
    params: Optional["str | os.PathLike[str]"] = None,
) -> OrbitResult:
    """Every periodic orbit of the loop with gains ``kp`` (1/s^2), ``kd`` (1/s); with ``k > 0``
    (1/(J s^2)) the orbits of the adapted loop, E_av = ``energy_avg`` (J; default: the k = 0
    orbit's). ``impact``: landing impact law; ``params``: a model TOML file."""
    txt = _core.orbit(kp, kd, k, energy_avg, impact, _path("params", params))
    r = json.loads(txt)
    sols = [
        Orbit(
            beta0=o["beta0"],
            beta_dot0=o["beta_dot0"],
            t_end=o["t_end"],
            period=o["period"],
            max_tilt=o["max_tilt"],
            energy_avg=o["energy_avg"],
            multipliers=np.array(o["multipliers"], dtype=float).reshape(-1, 2),
            stable=o["stable"],
            raw=o,
        )
        for o in r["solutions"]
    ]
    return OrbitResult(r["kp"], r["kd"], r["k"], r["energy_avg_adaptation"], sols, r)


@dataclass
class SinusoidResult:
    """``tilting plan sinusoid``: the frequency of approach 1 (the report's fields in
    ``report``: amplitude (rad), omega (rad/s), period (s), tilt_time, landing_time (s),
    max_tilt (rad), side, other_roots)."""

    omega: float  #: w (rad/s)
    period: float  #: T = 2 pi / w (s)
    report: Dict[str, Any]


def sinusoid(
    amplitude: float = 0.33,
    landing_offset: float = -0.5,
    omega_min: float = 0.5,
    omega_max: float = 30.0,
    impact: str = "paper",
    params: Optional["str | os.PathLike[str]"] = None,
) -> SinusoidResult:
    """The frequency w of beta_d = A sin(w t) + pi/2 (``amplitude`` A in rad) whose
    ideal-tracking tilt lands at t_l = T/2 + s t_t (``landing_offset`` s in (-1, 1)), searched
    in [``omega_min``, ``omega_max``] (rad/s)."""
    txt = _core.sinusoid(amplitude, landing_offset, omega_min, omega_max, impact, _path("params", params))
    r = json.loads(txt)
    return SinusoidResult(r["omega"], r["period"], r)


@dataclass
class BifurcationResult:
    """``tilting plan bifurcation`` (Fig. 8): the tilt peaks over the adaptation gain k."""

    k: np.ndarray  #: the values of k (1/(J s^2))
    peaks: List[np.ndarray]  #: |alpha| of the last ``keep`` tilts of each k (rad)
    period: List[Any]  #: period of the peaks: a number, "irregular", or None after a fault
    fault: List[Optional[str]]  #: what ended each run early, if anything
    energy_avg: float  #: E_av of the k = 0 orbit (J)
    k_star: Optional[float]  #: where a multiplier of the adapted orbit crosses -1
    k_onset_observed: Optional[float]  #: first k whose peaks are not period 1
    report: Dict[str, Any]  #: the CLI's JSON (``timing``: wall times, s)


def _bifurcation_result(txt: str) -> BifurcationResult:
    r = json.loads(txt)
    rows = r["rows"]
    return BifurcationResult(
        k=np.array([row["k"] for row in rows], dtype=float),
        peaks=[np.array(row["peaks"], dtype=float) for row in rows],
        period=[row["period"] for row in rows],
        fault=[row["fault"] for row in rows],
        energy_avg=r["energy_avg"],
        k_star=r["k_star"],
        k_onset_observed=r["k_onset_observed"],
        report=r,
    )


def bifurcation(
    k_from: float = 1500.0,
    k_to: float = 2500.0,
    k_step: float = 10.0,
    tilts: int = 500,
    keep: int = 200,
    kp: float = _KP,
    kd: float = _KD,
    period_tol: float = 1e-5,
    impact: str = "paper",
    params: Optional["str | os.PathLike[str]"] = None,
    client: Optional[Any] = None,
    partitions: Optional[int] = None,
) -> BifurcationResult:
    """The sweep of the adaptation gain k from ``k_from`` to ``k_to`` step ``k_step``
    (1/(J s^2)): ``tilts`` tilts simulated per k, the last ``keep`` kept; K_P0 = ``kp``
    (1/s^2), K_D = ``kd`` (1/s); peaks closer than ``period_tol`` (rad) are equal. On the local
    cores, or on the Dask ``client`` in ``partitions`` shards."""
    job = _core.bifurcation_job(
        k_from, k_to, k_step, tilts, keep, kp, kd, period_tol, impact, _path("params", params)
    )
    return _bifurcation_result(run_sharded("bifurcation", job, client, partitions))


@dataclass
class GainsResult:
    """``tilting plan gains`` (Fig. 6): the orbits over a (K_P, K_D) grid."""

    kp: np.ndarray  #: K_P of each cell (1/s^2)
    kd: np.ndarray  #: K_D of each cell (1/s)
    max_tilt: List[np.ndarray]  #: maximal tilt (rad) of each orbit found in the cell
    stable: List[np.ndarray]  #: whether each of them is stable
    report: Dict[str, Any]


def gains(
    kp_from: float = 60.0,
    kp_to: float = 140.0,
    kp_step: float = 20.0,
    kd_from: float = 8.0,
    kd_to: float = 20.0,
    kd_step: float = 1.0,
    impact: str = "paper",
    params: Optional["str | os.PathLike[str]"] = None,
    client: Optional[Any] = None,
    partitions: Optional[int] = None,
) -> GainsResult:
    """The maximal tilt angle of the orbits over K_P in [``kp_from``, ``kp_to``] step
    ``kp_step`` (1/s^2) × K_D in [``kd_from``, ``kd_to``] step ``kd_step`` (1/s); the rows of
    constant K_P run in parallel (on the Dask ``client``: ``partitions`` shards of rows)."""
    job = _core.gains_job(
        [kp_from, kp_to, kp_step], [kd_from, kd_to, kd_step], impact, _path("params", params)
    )
    r = json.loads(run_sharded("gains", job, client, partitions))
    cells = r["cells"]
    return GainsResult(
        kp=np.array([c["kp"] for c in cells], dtype=float),
        kd=np.array([c["kd"] for c in cells], dtype=float),
        max_tilt=[np.array(c["max_tilt"], dtype=float) for c in cells],
        stable=[np.array(c["stable"], dtype=bool) for c in cells],
        report=r,
    )


@dataclass
class MarginsResult:
    """``tilting plan margins``: what the stabilised orbit survives.

    ``survived`` is the delay × loss map of the plain controller as a boolean array of shape
    (len(delays), len(losses)) (``survived_predict``: with ``--predict auto``); ``last_peak``
    the mean |peak| of the last 10 tilts (rad) on the same grid. The rate maps and the robot's
    imperfection maps, the boundaries and the criteria are in ``report`` (the CLI's JSON).
    """

    delays: np.ndarray  #: total delays (s): the rows
    losses: np.ndarray  #: loss probabilities: the columns
    survived: np.ndarray
    survived_predict: np.ndarray
    last_peak: np.ndarray
    nominal_peak: float  #: the nominal mean |peak| (rad), 1 kHz over a perfect network
    report: Dict[str, Any]


def margins(
    delays: Sequence[float] = (0, 0.002, 0.004, 0.006, 0.008, 0.010, 0.015, 0.020),
    losses: Sequence[float] = (0, 0.05, 0.1, 0.2, 0.3, 0.5),
    rate: float = 1000.0,
    rates: Sequence[float] = (1000, 500, 250, 200, 150, 100, 75, 60, 50),
    tilts: int = 200,
    tolerance: float = 0.25,
    watchdog: int = 50,
    seed: int = 0,
    angle_noises: Sequence[float] = (0, 0.001, 0.003, 0.005, 0.007, 0.01, 0.02),
    rate_noises: Sequence[float] = (0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.1),
    mass_errors: Sequence[float] = (-0.1, -0.05, -0.03, -0.02, -0.01, 0, 0.01, 0.02, 0.05, 0.1),
    client: Optional[Any] = None,
    partitions: Optional[int] = None,
) -> MarginsResult:
    """The survey of ``tilting plan margins`` with its flags' defaults: delays (s), losses,
    the rate of the delay × loss map (Hz), the rates of the rate map (Hz), the tilts a point
    must complete, the peak tolerance (relative), the watchdog (periods), the links' seed,
    and the robot's maps (angle noise rad, rate noise rad/s, relative mass errors). On the
    local cores, or on the Dask ``client`` in ``partitions`` shards."""
    job = _core.margins_survey(
        _floats("delays", delays),
        _floats("losses", losses),
        rate,
        _floats("rates", rates),
        _floats("angle_noises", angle_noises),
        _floats("rate_noises", rate_noises),
        _floats("mass_errors", mass_errors),
        seed,
        tilts,
        watchdog,
        tolerance,
    )
    r = json.loads(run_sharded("margins", job, client, partitions))
    nd, nl = len(delays), len(losses)

    def grid(points: List[Dict[str, Any]], key: str, dtype: Any) -> np.ndarray:
        return np.array([p[key] for p in points], dtype=dtype).reshape(nd, nl)

    return MarginsResult(
        delays=np.array(_floats("delays", delays)),
        losses=np.array(_floats("losses", losses)),
        survived=grid(r["delay_loss"], "survived", bool),
        survived_predict=grid(r["delay_loss_predict"], "survived", bool),
        last_peak=grid(r["delay_loss"], "last_peak", float),
        nominal_peak=r["nominal_peak"],
        report=r,
    )


@dataclass(frozen=True)
class MarginsPoint:
    """The verdict on one Monte-Carlo point (:func:`margins_point`)."""

    survived: bool  #: every survival criterion holds
    tilts: int  #: tilts completed
    last_peak: float  #: mean |peak| of the last 10 tilts (rad); 0 with fewer tilts
    why: str  #: why it did not survive (empty if it did)


_POINT_DEFAULTS: Dict[str, Any] = dict(
    delay=0.0,
    loss=0.0,
    angle_noise=0.0,
    rate_noise=0.0,
    mass_error=0.0,
    rate=1000.0,
    predict=False,
    seed=0,
    tilts=200,
    watchdog=50,
    tolerance=0.25,
)


def _margins_batch(points: List[Dict[str, Any]], threads: int = 0) -> List[MarginsPoint]:
    """Runs points of :func:`margins_point` on ``threads`` cores (0: all) in Rust."""
    full = []
    for p in points:
        unknown = set(p) - set(_POINT_DEFAULTS)
        if unknown:
            raise UsageError(
                f"margins_point(): unknown option `{sorted(unknown)[0]}`; the options are "
                + ", ".join(_POINT_DEFAULTS)
            )
        full.append({**_POINT_DEFAULTS, **p})
    out: List[Optional[MarginsPoint]] = [None] * len(full)
    # One call per set of criteria (the nominal peak depends on them).
    groups: Dict[Tuple[Any, Any, Any], List[int]] = {}
    for i, p in enumerate(full):
        groups.setdefault((p["tilts"], p["watchdog"], p["tolerance"]), []).append(i)
    for (tilts, watchdog, tolerance), idx in groups.items():
        col = lambda k, f: [f(full[i][k]) for i in idx]  # noqa: E731
        num = lambda k: _floats(k, [full[i][k] for i in idx])  # noqa: E731
        survived, ntilts, peak, why = _core.margins_points(
            num("delay"),
            num("loss"),
            num("angle_noise"),
            num("rate_noise"),
            num("mass_error"),
            num("rate"),
            col("predict", bool),
            col("seed", int),
            tilts,
            watchdog,
            tolerance,
            threads,
        )
        for j, i in enumerate(idx):
            out[i] = MarginsPoint(survived[j], ntilts[j], peak[j], why[j])
    return out  # type: ignore[return-value]


def margins_point(
    delay: float = 0.0,
    loss: float = 0.0,
    angle_noise: float = 0.0,
    rate_noise: float = 0.0,
    mass_error: float = 0.0,
    rate: float = 1000.0,
    predict: bool = False,
    seed: int = 0,
    tilts: int = 200,
    watchdog: int = 50,
    tolerance: float = 0.25,
) -> MarginsPoint:
    """One Monte-Carlo point of the margins study: the paper's stabilised orbit at ``rate``
    (Hz) over a constant ``delay`` (s, state and torque together) and Bernoulli ``loss`` of
    each direction, on a robot with sensor noise (``angle_noise`` rad, ``rate_noise`` rad/s,
    standard deviations) and a relative arm-mass error, the controller predicting if
    ``predict``; the link and the noise drawn from ``seed``. Judged by the criteria of
    ``tilting plan margins`` (``tilts``, ``watchdog`` periods, peak ``tolerance``).

    Has a ``batch`` form for :func:`tilting.sweep`: a grid's points run on all cores in Rust,
    or one core per task on Dask."""
    return _margins_batch(
        [
            dict(
                delay=delay,
                loss=loss,
                angle_noise=angle_noise,
                rate_noise=rate_noise,
                mass_error=mass_error,
                rate=rate,
                predict=predict,
                seed=seed,
                tilts=tilts,
                watchdog=watchdog,
                tolerance=tolerance,
            )
        ],
        threads=1,
    )[0]


margins_point.batch = _margins_batch  # type: ignore[attr-defined]
