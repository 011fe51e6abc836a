"""Sweeps of independent points: on the local cores, or on a Dask cluster.

A point's result depends on its coordinates only: its seed is derived from them
(:func:`point_seed`), never from the order in which points run, so a sweep gives the same
results bit for bit with or without a client and however it is partitioned.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import os
import struct
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Sequence

from . import _core
from ._core import UsageError

Point = Dict[str, Any]


def _canonical(v: Any) -> bytes:
    if isinstance(v, bool):
        return b"b1" if v else b"b0"
    if isinstance(v, int):
        return b"i" + str(v).encode()
    if isinstance(v, float):
        return b"f" + struct.pack("<d", v)
    if isinstance(v, str):
        return b"s" + v.encode()
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise TypeError(f"a coordinate must be a number, bool or string, not {type(v).__name__}")
    return b"f" + struct.pack("<d", f)


def point_seed(coords: Dict[str, Any], replicate: int = 0, base_seed: int = 0) -> int:
    """A 64-bit seed derived from a point's coordinates (names and exact values, in any order),
    its replicate number and a base seed: the same point always gets the same seed, on any
    machine, in any process, whatever else runs."""
    h = hashlib.blake2b(digest_size=8)
    for k in sorted(coords):
        h.update(k.encode() + b"=" + _canonical(coords[k]) + b";")
    h.update(b"#" + str(int(replicate)).encode() + b"@" + str(int(base_seed)).encode())
    return int.from_bytes(h.digest(), "little")


class Grid:
    """The product of named axes (the first one outermost), each point repeated
    ``replicates`` times with the seed :func:`point_seed` derives from its coordinates and
    replicate number (the key ``seed``): ``Grid(delay=[0, 0.004], loss=[0, 0.1],
    replicates=10)`` has 40 points."""

    def __init__(self, replicates: int = 1, base_seed: int = 0, **axes: Sequence[Any]):
        if isinstance(replicates, bool) or not isinstance(replicates, int) or replicates < 1:
            raise UsageError(f"invalid `replicates` = {replicates!r}: must be an integer >= 1")
        if "seed" in axes:
            raise UsageError("`seed` is derived from the coordinates: give `base_seed` instead")
        self.axes = {k: list(v) for k, v in axes.items()}
        for k, v in self.axes.items():
            if not v:
                raise UsageError(f"invalid axis `{k}`: give at least one value")
        self.replicates = replicates
        self.base_seed = base_seed

    def __len__(self) -> int:
        return math.prod(len(v) for v in self.axes.values()) * self.replicates

    def __iter__(self) -> Iterator[Point]:
        names = list(self.axes)
        for values in itertools.product(*self.axes.values()):
            coords = dict(zip(names, values))
            for r in range(self.replicates):
                yield {**coords, "seed": point_seed(coords, r, self.base_seed)}


def _partitions(n: int, parts: int) -> List[List[int]]:
    """Strided partitions of ``range(n)`` (the slow and the fast corners of a grid spread)."""
    return [list(range(i, n, parts)) for i in range(parts)]


def _workers_threads(client: Any) -> int:
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001 - any client-like object
        return 1


def _run_part(fn: Callable[..., Any], points: List[Point]) -> List[Any]:
    """Runs a partition in a worker: the batch form if ``fn`` has one (one core: the
    worker's other threads run other partitions), else point by point."""
    batch = getattr(fn, "batch", None)
    if batch is not None:
        return batch(points, threads=1)
    return [fn(**p) for p in points]


def sweep(
    fn: Callable[..., Any],
    grid: Iterable[Point],
    client: Optional[Any] = None,
    *,
    partitions: Optional[int] = None,
) -> List[Any]:
    """``[fn(**point) for point in grid]``, in the grid's order, computed in parallel.

    Without ``client``: on the local cores (a function with a ``batch`` form, such as
    :func:`tilting.plan.margins_point`, runs its points on all cores in Rust; others run in a
    thread pool, in parallel where they release the GIL). With a Dask ``client``: the points
    are split into ``partitions`` strided partitions (default: twice the cluster's threads),
    one task each. The results are the same bit for bit either way.
    """
    points = list(grid)
    for p in points:
        if not isinstance(p, dict):
            raise TypeError(f"sweep(): a grid point must be a dict of keyword arguments, not {type(p).__name__}")
    if client is None:
        batch = getattr(fn, "batch", None)
        if batch is not None:
            return batch(points, threads=0)
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as ex:
            return list(ex.map(lambda p: fn(**p), points))
    n = len(points)
    if n == 0:
        return []
    if partitions is None:
        partitions = 2 * _workers_threads(client)
    if isinstance(partitions, bool) or not isinstance(partitions, int) or partitions < 1:
        raise UsageError(f"invalid `partitions` = {partitions!r}: must be an integer >= 1")
    parts = [p for p in _partitions(n, min(partitions, n)) if p]
    futures = client.map(
        _run_part,
        [fn] * len(parts),
        [[points[j] for j in part] for part in parts],
        pure=False,
    )
    results: List[Any] = [None] * n
    for part, res in zip(parts, client.gather(futures)):
        for j, r in zip(part, res):
            results[j] = r
    return results


def _shard(kind: str, job: str, index: int, count: int) -> str:
    """One shard of a sweep, in a worker (a module-level function: pickled by name)."""
    return _core.run_shard(kind, job, index, count)


def run_sharded(kind: str, job: str, client: Optional[Any], partitions: Optional[int]) -> str:
    """The report (JSON) of a whole sweep (``kind``: margins, bifurcation, gains) described
    by ``job`` (JSON): on the local cores without ``client``, else as ``partitions`` shards
    (default: twice the cluster's threads), one Dask task each, merged like ``tilting plan
    merge``."""
    if client is None:
        return _core.run_whole(kind, job)
    if partitions is None:
        partitions = 2 * _workers_threads(client)
    if isinstance(partitions, bool) or not isinstance(partitions, int) or partitions < 1:
        raise UsageError(f"invalid `partitions` = {partitions!r}: must be an integer >= 1")
    futures = client.map(
        _shard,
        [kind] * partitions,
        [job] * partitions,
        list(range(partitions)),
        [partitions] * partitions,
        pure=False,
    )
    return _core.merge(kind, job, client.gather(futures))
