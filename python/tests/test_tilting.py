"""The Python package against the CLI: the same options give the same reports, bit for bit
(JSON floats parse exactly, so equal dicts mean equal bits), and bad input is refused with the
CLI's messages."""

import json
import math

import numpy as np
import pytest

tilting = pytest.importorskip("tilting", reason="SKIP: the tilting package is not installed")
from conftest import without  # noqa: E402

WALL = "stats.wall_time_s"


@pytest.mark.parametrize(
    "opts",
    [
        dict(duration=3.0),
        dict(duration=2.0, control_period=0.001, delay=0.004, loss=0.1, seed=3),
        dict(duration=2.0, k=0, kp=90.0, x0=[0.0, 1.4, 0.0, 1.0], mode="flat"),
    ],
)
def test_simulate_equals_the_cli(cli, opts):
    args = []
    for k, v in opts.items():
        v = ",".join(map(repr, v)) if isinstance(v, list) else v
        args.append(f"--{k.replace('_', '-')}={v}")
    want = json.loads(cli("simulate", "--json", *args))
    r = tilting.simulate(**opts)
    assert without(r.summary, WALL) == without(want, WALL)
    assert r.events == want["events"] and r.peaks == want["tilt_peaks"]
    # The arrays: time ordered, the state's shape, the modes the events name, and the last
    # sample is the final state of the report.
    n = len(r.t)
    assert r.x.shape == (n, 4) and r.mode.shape == (n,) and r.torque.shape == (n,)
    assert np.all(np.diff(r.t) >= 0) and r.t[0] == 0.0
    assert r.t[-1] == pytest.approx(want["final"]["t"], abs=1e-12)
    assert np.array_equal(r.x[-1], np.array(want["final"]["x"]))
    seen = {tilting.MODES[m] for m in np.unique(r.mode)}
    named = {e["to"] for e in want["events"]} | {e["from"] for e in want["events"]}
    assert seen == named | ({"left"} if not named else set())
    assert np.all(np.isfinite(r.torque))


def test_simulate_torque_is_the_law_at_rest():
    # Flat and at rest at the upright reference, the PD law commands only gravity
    # compensation; the torque column is finite and the arm's peak torque is bounded.
    r = tilting.simulate(duration=1.0)
    assert np.max(np.abs(r.torque)) < 50.0


def test_plan_orbit_sinusoid_gains_equal_the_cli(cli):
    o = tilting.plan.orbit(kp=100, kd=15)
    assert o.report == json.loads(cli("plan", "orbit", "--json", "--kp", "100", "--kd", "15"))
    assert o.solutions and all(s.multipliers.shape[1] == 2 for s in o.solutions)
    s = tilting.plan.sinusoid(amplitude=0.33)
    assert s.report == json.loads(cli("plan", "sinusoid", "--json", "--amplitude", "0.33"))
    assert s.period == pytest.approx(2 * math.pi / s.omega, rel=1e-12)
    g = tilting.plan.gains(kp_from=80, kp_to=100, kp_step=20, kd_from=10, kd_to=11)
    want = cli("plan", "gains", "--json", "--kp-from", "80", "--kp-to", "100", "--kp-step",
               "20", "--kd-from", "10", "--kd-to", "11")
    assert g.report == json.loads(want)
    assert list(g.kp) == [80, 80, 100, 100] and list(g.kd) == [10, 11, 10, 11]


MARGINS = dict(tilts=20, delays=[0, 0.02], losses=[0, 0.2], rates=[1000, 50],
               angle_noises=[0, 0.003], rate_noises=[0.02], mass_errors=[0, 1], seed=7)


# The robot rows of `plan margins` (parameter bands, friction, estimators: bisections) are the
# CLI's only; the package's `margins` maps the grids, so the CLI is asked for the grids alone.
NO_ROBOT_ROWS = ["--param-bands", "none", "--viscous-span", "0", "--coulomb-span", "0",
                 "--noise-span", "0", "--encoder-bits", "none"]


def margins_cli_args():
    args = []
    for k, v in MARGINS.items():
        v = ",".join(map(str, v)) if isinstance(v, list) else v
        args += [f"--{k.replace('_', '-')}", str(v)]
    return args + NO_ROBOT_ROWS


def test_margins_equal_the_cli(cli):
    want = json.loads(cli("plan", "margins", "--json", *margins_cli_args()))
    m = tilting.plan.margins(**MARGINS)
    assert m.report == want
    assert m.survived.shape == (2, 2)
    assert m.survived[0, 0] and not m.survived[1, 0]  # 20 ms is past the 9 ms limit


def test_bifurcation_equals_the_cli(cli):
    opts = dict(k_from=1500, k_to=1520, k_step=10, tilts=60, keep=20)
    args = [f"--{k.replace('_', '-')}={v}" for k, v in opts.items()]
    want = json.loads(cli("plan", "bifurcation", "--json", *args))
    b = tilting.plan.bifurcation(**opts)
    assert without(b.report, "timing") == without(want, "timing")
    assert list(b.k) == [1500, 1510, 1520] and all(len(p) == 20 for p in b.peaks)


def test_read_mcap_reads_what_simulate_records(cli, tmp_path):
    path = tmp_path / "run.mcap"
    summary = json.loads(
        cli("simulate", "--json", "--duration", "1", "--control-period", "0.001", "--record", path)
    )
    rec = tilting.read_mcap(path)
    # The logged loop samples every 1 ms and answers every state.
    assert len(rec.t) == pytest.approx(1000, abs=2)
    assert np.allclose(np.diff(rec.t), 1e-3, atol=1e-9)
    assert np.all(np.isfinite(rec.torque[:-1]))
    assert len(rec.events) == len(summary["events"])
    assert rec.robot is not None


def test_bad_input_is_refused_with_the_cli_messages():
    with pytest.raises(TypeError, match="`duration` must be a number"):
        tilting.simulate(duration={"s": 1})
    with pytest.raises(tilting.UsageError, match="duration"):
        tilting.simulate(duration=float("nan"))
    with pytest.raises(tilting.UsageError, match="unexpected argument '--no-such-option'"):
        tilting.simulate(no_such_option=1)
    with pytest.raises(tilting.UsageError, match="output flag"):
        tilting.simulate(json=True)
    with pytest.raises(tilting.UsageError, match=r"invalid `--delays` value NaN: allowed 0 to 60"):
        tilting.plan.margins(delays=[float("nan")])
    with pytest.raises(TypeError, match="`losses` must be a list of numbers"):
        tilting.plan.margins(losses="0.1")
    with pytest.raises(TypeError):
        tilting.plan.orbit(kp="fast")
    with pytest.raises(tilting.UsageError, match=r"invalid `--kd` = -1"):
        tilting.plan.orbit(kd=-1)
    with pytest.raises(tilting.UsageError, match="`--keep`"):
        tilting.plan.bifurcation(tilts=10, keep=20)
    with pytest.raises(tilting.UsageError, match="unknown option `dely`"):
        tilting.plan.margins_point.batch([{"dely": 0.1}])
    with pytest.raises(tilting.UsageError, match="invalid `loss` = 2"):
        tilting.plan.margins_point(loss=2.0)
    with pytest.raises(tilting.UsageError, match=r"the shard index I must be in 0..=2"):
        tilting._core.run_shard("gains", "{}", 3, 3)


def test_shards_of_two_grids_do_not_merge():
    from tilting import _core
    a = _core.gains_job([80, 100, 20], [10, 11, 1], "paper", None)
    b = _core.gains_job([80, 100, 20], [10, 12, 1], "paper", None)
    shards = [_core.run_shard("gains", a, 0, 2), _core.run_shard("gains", b, 1, 2)]
    # Shard 1 of the other grid (one more K_D per row): refused, naming the field.
    with pytest.raises(tilting.UsageError, match=r"different grid \(`kds\[2\]`|different grid \(`kds`"):
        _core.merge("gains", a, shards)
    with pytest.raises(tilting.UsageError, match="missing"):
        _core.merge("gains", a, shards[:1])


def test_grid_seeds_derive_from_coordinates():
    g = list(tilting.Grid(delay=[0.0, 0.004], loss=[0.0, 0.1], replicates=3))
    assert len(g) == 12 and len({p["seed"] for p in g}) == 12
    # Reordered axes: the same points get the same seeds.
    h = list(tilting.Grid(loss=[0.1, 0.0], delay=[0.004, 0.0], replicates=3))
    key = lambda p: (p["delay"], p["loss"], p["seed"])  # noqa: E731
    assert sorted(map(key, g)) == sorted(map(key, h))


def test_sweep_without_client_equals_point_by_point():
    grid = list(tilting.Grid(delay=[0.0, 0.02], loss=[0.0, 0.3], tilts=[20], replicates=2))
    got = tilting.sweep(tilting.plan.margins_point, grid)
    one = [tilting.plan.margins_point(**p) for p in grid]
    assert got == one
    assert any(r.survived for r in got) and not all(r.survived for r in got)
