"""Sweeps on a Dask LocalCluster of 2 worker processes: the same results, bit for bit, as the
local run and as the CLI, whatever the partitioning. Skipped when dask is not installed."""

import json

import pytest

tilting = pytest.importorskip("tilting", reason="SKIP: the tilting package is not installed")
distributed = pytest.importorskip("dask.distributed", reason="SKIP: dask is not installed")
from conftest import without  # noqa: E402
from test_tilting import MARGINS, margins_cli_args  # noqa: E402


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_margins_on_dask_equal_local_and_cli(client, cli):
    want = json.loads(cli("plan", "margins", "--json", *margins_cli_args()))
    local = tilting.plan.margins(**MARGINS)
    assert local.report == want
    for parts in (1, 3, 17, 40):
        d = tilting.plan.margins(**MARGINS, client=client, partitions=parts)
        assert d.report == want, parts


def test_bifurcation_on_dask_equals_local(client):
    opts = dict(k_from=1500, k_to=1540, k_step=10, tilts=60, keep=20)
    local = tilting.plan.bifurcation(**opts)
    for parts in (2, 5):
        d = tilting.plan.bifurcation(**opts, client=client, partitions=parts)
        assert without(d.report, "timing") == without(local.report, "timing")


def test_sweep_on_dask_equals_local_whatever_the_partitioning(client):
    grid = tilting.Grid(delay=[0.0, 0.006, 0.02], loss=[0.0, 0.2], tilts=[20], replicates=2)
    local = tilting.sweep(tilting.plan.margins_point, grid)
    for parts in (1, 4, 12):
        assert tilting.sweep(tilting.plan.margins_point, grid, client, partitions=parts) == local
    # A plain Python function (no batch form) runs too, in grid order.
    pts = list(grid)
    assert tilting.sweep(_delay_times_two, pts, client) == [2 * p["delay"] for p in pts]


def _delay_times_two(delay, **_):
    return 2 * delay
