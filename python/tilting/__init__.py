"""The tilting system from Python: the simulator, the planner and the margins maps of the Rust
crates, with numpy arrays back; sweeps on the local cores or on a Dask cluster.

- :func:`simulate`: ``tilting simulate`` with the same options (keyword arguments named as the
  CLI's flags, ``-`` written ``_``), returning arrays and the report;
- :mod:`tilting.plan`: ``orbit``, ``sinusoid``, ``bifurcation``, ``gains``, ``margins`` (the
  last three optionally on a Dask ``client``), and ``margins_point`` for Monte-Carlo studies;
- :func:`sweep`: any function over a :class:`Grid` of points, locally or on Dask;
- :func:`read_mcap`: a recording of ``tilting live`` / ``simulate --record`` as arrays.

Units: SI throughout (s, rad, rad/s, N m, J, Hz). Invalid input raises :class:`UsageError`
(a ``ValueError``) with the CLI's message, naming the flag and its allowed range; a wrong type
raises ``TypeError``; a computation that fails raises :class:`RunError`.
"""

from __future__ import annotations

import json
import numbers
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

import numpy as np

from . import _core
from ._core import RunError, UsageError
from ._sweep import Grid, point_seed, sweep

__all__ = [
    "simulate",
    "SimulationResult",
    "read_mcap",
    "Recording",
    "sweep",
    "Grid",
    "point_seed",
    "UsageError",
    "RunError",
    "plan",
    "MODES",
]

#: The contact modes by their code in the ``mode`` arrays (the paper's index q).
MODES = ("flat", "left", "right")


def _number(name: str, v: Any, where: str) -> str:
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise TypeError(
            f"{where}: option `{name}` must be a number, a string, a bool or a list of "
            f"numbers, not {type(v).__name__}"
        )
    if isinstance(v, numbers.Integral):
        return str(int(v))
    return repr(float(v))


def _argv(options: Dict[str, Any], where: str) -> List[str]:
    """The CLI flags (``--name=value``) of keyword arguments."""
    argv = []
    for name, v in options.items():
        flag = "--" + name.replace("_", "-")
        if v is None or v is False:
            continue
        if v is True:
            argv.append(flag)
        elif isinstance(v, (str, os.PathLike)):
            argv.append(f"{flag}={os.fspath(v)}")
        elif isinstance(v, (list, tuple, np.ndarray)):
            argv.append(f"{flag}=" + ",".join(_number(name, e, where) for e in v))
        else:
            argv.append(f"{flag}={_number(name, v, where)}")
    return argv


@dataclass
class SimulationResult:
    """One run of :func:`simulate`.

    Arrays (one entry per recorded sample: every transition and at most about 20,000 samples
    evenly spaced in time):

    - ``t``: plant time (s);
    - ``x``: state, shape (n, 4): ``alpha`` (plate tilt, rad), ``beta`` (arm angle, rad),
      ``alpha_dot``, ``beta_dot`` (rad/s);
    - ``mode``: contact mode code (0 flat, 1 left, 2 right; :data:`MODES`);
    - ``torque``: the joint torque the law commands at that state (N m); in a sampled loop the
      plant applies the one computed at the last sample time.

    ``summary`` is the report ``tilting simulate --json`` prints (``json`` its text, byte for
    byte); ``events`` (mode transitions) and ``peaks`` (the extreme ``alpha`` of each tilt)
    are its lists.
    """

    t: np.ndarray
    x: np.ndarray
    mode: np.ndarray
    torque: np.ndarray
    summary: Dict[str, Any]
    json: str
    events: List[Dict[str, Any]] = field(default_factory=list)
    peaks: List[Dict[str, Any]] = field(default_factory=list)

    @property
    def fault(self) -> Optional[str]:
        """What ended the run early, if anything."""
        return self.summary.get("fault")


def simulate(**options: Any) -> SimulationResult:
    """Runs ``tilting simulate`` with these options (the CLI's flags, ``-`` written ``_``):
    e.g. ``simulate(duration=5.0, k=500, control_period=0.001, delay=0.004)``.

    A flag without a value takes ``True`` (``False`` or ``None`` leave it out); a list flag
    takes a list. The output flags of the CLI (``json``, ``plot``, ``record``, ``robot``) are
    not options here: the result carries the report and the arrays. The GIL is released
    while the loop runs.
    """
    for out in ("json", "plot", "record", "robot"):
        if out in options:
            raise UsageError(
                f"simulate(): `{out}` is an output flag of the CLI, not an option here (the "
                "result carries the report and the arrays)"
            )
    d = _core.simulate(_argv(options, "simulate()"))
    summary = json.loads(d["json"])
    return SimulationResult(
        t=d["t"],
        x=d["x"],
        mode=d["mode"],
        torque=d["torque"],
        summary=summary,
        json=d["json"],
        events=summary.get("events", []),
        peaks=summary.get("tilt_peaks", []),
    )


@dataclass
class Recording:
    """A recording read by :func:`read_mcap`: every state the controller read.

    ``t`` (s), ``x`` (n x 4: alpha, beta in rad; alpha_dot, beta_dot in rad/s; NaN for a rate
    the plant did not measure), ``mode`` (0 flat, 1 left, 2 right), ``torque`` (N m, the torque
    answered to each state, held until the next; NaN where none was answered), ``events``
    (mode transitions), ``end`` (s), ``stopped_early``, ``robot`` (the channels' robot name).
    """

    t: np.ndarray
    x: np.ndarray
    mode: np.ndarray
    torque: np.ndarray
    events: List[Dict[str, Any]]
    end: float
    stopped_early: bool
    robot: Optional[str]
    source: str


def read_mcap(path: "str | os.PathLike[str]") -> Recording:
    """Reads an MCAP recording (or a live run's directory holding ``run.mcap``) as arrays."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"read_mcap(): `path` must be a path, not {type(path).__name__}")
    d = _core.read_mcap(os.fspath(path))
    return Recording(
        t=d["t"],
        x=d["x"],
        mode=d["mode"],
        torque=d["torque"],
        events=json.loads(d["events"]),
        end=d["end"],
        stopped_early=d["stopped_early"],
        robot=d["robot"],
        source=str(d["source"]),
    )


from . import plan  # noqa: E402  (plan uses the helpers above)
