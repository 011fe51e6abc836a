"""Benchmark: a Monte-Carlo margins study (delay x loss x angle noise x mass error x seeds)
on a Dask LocalCluster of 2 worker processes against the local rayon run of the same grid,
and Python's call overhead for one short simulate. Prints the throughput ratio, Dask's
per-point overhead and the call overhead; checks the two runs agree point for point.

    python3 examples/python/dask_bench.py              # 10,000 points, 20 tilts each
    python3 examples/python/dask_bench.py --points 2000 --tilts 20
"""

import argparse
import os
import time

import tilting


def grid(points, tilts):
    # 5 delays x 4 losses x 5 angle noises x 4 mass errors = 400 coordinates, x replicates.
    axes = dict(
        delay=[0.0, 0.002, 0.004, 0.006, 0.008],
        loss=[0.0, 0.05, 0.1, 0.2],
        angle_noise=[0.0, 0.001, 0.002, 0.003, 0.005],
        mass_error=[-0.02, 0.0, 0.02, 0.05],
        tilts=[tilts],
    )
    n = 1
    for v in axes.values():
        n *= len(v)
    return tilting.Grid(replicates=max(1, points // n), base_seed=1, **axes)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=10_000)
    p.add_argument("--tilts", type=int, default=20)
    p.add_argument("--workers", type=int, default=2)
    a = p.parse_args()
    from dask.distributed import Client, LocalCluster

    g = list(grid(a.points, a.tilts))
    n = len(g)
    fn = tilting.plan.margins_point
    fn(**{**g[0], "tilts": a.tilts})  # the nominal run, once per process (cached)

    t0 = time.perf_counter()
    local = tilting.sweep(fn, g)
    t_local = time.perf_counter() - t0

    with LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        client.run(lambda: fn(tilts=a.tilts))  # warm the workers: import, nominal run
        t0 = time.perf_counter()
        dask = tilting.sweep(fn, g, client)
        t_dask = time.perf_counter() - t0
        # Dask's own cost per point: the same grid of no-op points through the same path.
        t0 = time.perf_counter()
        tilting.sweep(_noop, g, client)
        t_noop = time.perf_counter() - t0

    assert dask == local, "the Dask and local runs differ"
    survived = sum(r.survived for r in local)
    # Python's call overhead: one short simulate through the package against the same
    # simulation's own wall time (the report's wall_time_s, measured in Rust).
    reps = 50
    t0 = time.perf_counter()
    for _ in range(reps):
        r = tilting.simulate(duration=0.1)
    per_call = (time.perf_counter() - t0) / reps
    rust = r.summary["stats"]["wall_time_s"]

    print(f"grid: {n} points ({a.tilts} tilts each), {survived} survive; {os.cpu_count()} cores")
    print(f"local rayon:  {t_local:8.2f} s  {n / t_local:8.1f} points/s")
    print(f"Dask ({a.workers} workers): {t_dask:8.2f} s  {n / t_dask:8.1f} points/s")
    print(f"throughput ratio rayon/Dask: {t_dask / t_local:.3f} (target <= 1.3)")
    print(f"Dask per-point overhead: {1e6 * (t_dask - t_local) / n:.1f} us (wall, vs rayon); "
          f"no-op sweep through Dask: {1e6 * t_noop / n:.1f} us per point")
    print(f"simulate(duration=0.1): {1e3 * per_call:.3f} ms per call, of which the simulation "
          f"{1e3 * rust:.3f} ms: Python overhead {1e6 * (per_call - rust):.0f} us")


def _noop(**point):
    return point["seed"]


if __name__ == "__main__":
    main()
