#!/usr/bin/env python3
"""Many robots on one host (issue 32): N `tilting live` runs started together, each its own
robot (`--robot NAME`: its own zenoh keys tilting/NAME/..., its own ports, its own recorder),
for N in --n (default 1,2,4,8), at --rate Hz (default 1000) for --duration s (default 15).

Prints, per robot: periods missed (the plant's deadline misses / its periods), the loop's
latency p50/p99 (us, the plant's: state published -> its torque received, last 4096 periods),
overruns and the largest (us), whether the orbit holds (summary.json's verdict); per N: the
host's CPU use over the run (/proc/stat, busy share of all cores, %), and each node's resident
memory (MiB, VmRSS) and thread count (/proc/PID/task: zenoh's runtimes are most of them) 3 s
after start and at the last sample before it exits (flat memory is a standard here).

    python3 bench/robots_bench.py --n 1,2,4,8 --duration 15
    ZENOH_RUNTIME='(rx: (handover: app), acc: (handover: app), tx: (handover: app), \
        net: (handover: app), app: (worker_threads: 1))' python3 bench/robots_bench.py

ZENOH_RUNTIME (zenoh-runtime's RON map of runtime -> worker_threads, max_blocking_threads,
handover) is inherited by the nodes. No --realtime here: SCHED_FIFO on a shared machine starves
everything else; on a quiet machine add it with --live-args '--realtime 80'.
"""

import argparse
import json
import os
import shlex
import subprocess
import sys
import time


def cpu_times():
    """(busy, total) jiffies over all cores, from /proc/stat's first line."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    idle = v[3] + v[4]  # idle + iowait
    return sum(v) - idle, sum(v)


def node_stats(pid):
    """(VmRSS in MiB, thread count) of a live process, or None once it is gone."""
    try:
        with open(f"/proc/{pid}/status") as f:
            rss = next(int(l.split()[1]) for l in f if l.startswith("VmRSS:"))
        return rss / 1024.0, len(os.listdir(f"/proc/{pid}/task"))
    except (OSError, StopIteration):
        return None


def children(pid):
    """{comm: pid} of the nodes a `tilting live` started (tilting-plant, tilting-controller)."""
    out = {}
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            kids = [int(x) for x in f.read().split()]
    except OSError:
        return out
    for k in kids:
        try:
            with open(f"/proc/{k}/comm") as f:
                out[f.read().strip()] = k
        except OSError:
            pass
    return out


def run_n(args, n):
    outdir = os.path.join(args.out, f"n{n}")
    os.makedirs(outdir, exist_ok=True)
    busy0, total0 = cpu_times()
    procs = []
    for i in range(n):
        name = f"rb{n}x{i}_{os.getpid()}"
        d = os.path.join(outdir, f"r{i}")
        cmd = [args.bin, "live", "--duration", str(args.duration), "--rate", str(args.rate),
               "--robot", name, "--out", d] + shlex.split(args.live_args)
        log = open(os.path.join(outdir, f"r{i}.log"), "w")
        procs.append((name, d, subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)))
        time.sleep(args.stagger)
    first, last = {}, {}
    t0 = time.time()
    while any(p.poll() is None for _, _, p in procs):
        time.sleep(0.5)
        for name, _, p in procs:
            for comm, pid in children(p.pid).items():
                s = node_stats(pid)
                if s is None:
                    continue
                key = (name, comm)
                if key not in first and time.time() - t0 >= 3.0:
                    first[key] = s
                if key in first:
                    last[key] = s
    busy1, total1 = cpu_times()
    cpu = 100.0 * (busy1 - busy0) / max(1, total1 - total0)
    rows = []
    for name, d, p in procs:
        try:
            with open(os.path.join(d, "summary.json")) as f:
                s = json.load(f)
            pl = s["plant"]
            steps = max(1, pl["steps"])
            rows.append((name, pl["deadline_misses"], steps, pl["latency_us"]["p50"],
                         pl["latency_us"]["p99"], pl["overruns"], pl["max_overrun_us"],
                         s["orbit"]["state"]))
        except (OSError, KeyError, ValueError, TypeError) as e:
            rows.append((name, None, None, None, None, None, None, f"no summary ({e}); exit {p.returncode}"))
    return rows, cpu, first, last, time.time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", default="1,2,4,8", help="robot counts, comma-separated (1 to 32)")
    ap.add_argument("--duration", type=float, default=15.0, help="s per run (1 to 600)")
    ap.add_argument("--rate", type=float, default=1000.0, help="Hz (1 to 10000)")
    ap.add_argument("--bin", default="target/release/tilting", help="the tilting binary")
    ap.add_argument("--out", default="/tmp/robots_bench", help="run directories")
    ap.add_argument("--stagger", type=float, default=0.5,
                    help="s between starts (0 to 5): `live` picks its free ports by binding port 0 "
                         "and releasing it, so runs started at the same instant can be given the same "
                         "port (the controller then exits: address in use)")
    ap.add_argument("--live-args", default="", help="more flags for each `tilting live`")
    a = ap.parse_args()
    ns = [int(x) for x in a.n.split(",")]
    if not all(1 <= n <= 32 for n in ns):
        sys.exit(f"--n: each count in [1, 32], got {a.n}")
    if not 1.0 <= a.duration <= 600.0:
        sys.exit(f"--duration: in [1, 600] s, got {a.duration}")
    if not 1.0 <= a.rate <= 10000.0:
        sys.exit(f"--rate: in [1, 10000] Hz, got {a.rate}")
    if not 0.0 <= a.stagger <= 5.0:
        sys.exit(f"--stagger: in [0, 5] s, got {a.stagger}")
    print(f"ZENOH_RUNTIME={os.environ.get('ZENOH_RUNTIME', '(default)')}; rate {a.rate} Hz; "
          f"{a.duration} s; {os.cpu_count()} cores")
    for n in ns:
        load = open("/proc/loadavg").read().split()[:3]
        rows, cpu, first, last, wall = run_n(a, n)
        print(f"\nN = {n}: host CPU {cpu:.0f} % of all cores over {wall:.0f} s; load before "
              f"{' '.join(load)}")
        print(f"| {'robot':<22} | {'missed':>16} | {'p50 us':>7} | {'p99 us':>7} | "
              f"{'overruns (max us)':>18} | orbit")
        for name, miss, steps, p50, p99, ovr, ovmax, orbit in rows:
            if miss is None:
                print(f"| {name:<22} | {'-':>16} | {'-':>7} | {'-':>7} | {'-':>18} | {orbit}")
                continue
            m = f"{miss}/{steps} {100.0 * miss / steps:.2f}%"
            o = f"{ovr} ({ovmax:.0f})"
            print(f"| {name:<22} | {m:>16} | {p50:>7.1f} | {p99:>7.1f} | {o:>18} | {orbit}")
        for key in sorted(first):
            (r0, t0), (r1, t1) = first[key], last[key]
            print(f"  {key[0]} {key[1]}: RSS {r0:.1f} -> {r1:.1f} MiB, threads {t0} -> {t1}")


if __name__ == "__main__":
    main()
