#!/usr/bin/env python3
"""Many robots on one host (issue 32): N robots at once, each its own keys tilting/NAME/...,
for N in --n (default 1,2,4,8), at --rate Hz (default 1000) for --duration s (default 15), in
one or more forms (--forms, run alternately for each N so that they share the machine's load):

- `live`: N `tilting live --robot NAME` runs started together (each its own ports, recorder
  and front door: a plant and a controller process each);
- `pairs`: N bare `tilting-plant --robot NAME` / `tilting-controller --robot NAME` process
  pairs, no front door, no recorder;
- `host`: one `tilting-plant --robots A,B,...` and one `tilting-controller --robots A,B,...`
  (host mode: one process and one zenoh session serving every robot), no front door.

`pairs` against `host` is the like-for-like comparison of N process pairs with one host pair.
For the bare forms the orbit's verdict is live's criterion (`live/src/orbit.rs`) applied to the
plant's `tilt_peaks`: no fault, a tilt within the last 1.8 s, the last 10 tilts alternate, and
their mean |peak| within 25 % of --nominal-peak (0.0413 rad, the paper's k = 500 loop at 1 kHz).

Prints, per robot: periods missed (the plant's deadline misses / its periods), the loop's
latency p50/p99 (us, the plant's: state published -> its torque received, last 4096 periods),
overruns and the largest (us), whether the orbit holds (summary.json's verdict); per N: the
host's CPU use over the run (/proc/stat, busy share of all cores, %), and each node's resident
memory (MiB, VmRSS) and thread count (/proc/PID/task: zenoh's runtimes are most of them) 3 s
after start and at the last sample before it exits (flat memory is a standard here).

    python3 bench/robots_bench.py --n 1,2,4,8 --duration 15
    python3 bench/robots_bench.py --forms pairs,host --n 1,2,4,8 --duration 12
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


def sample(first, last, key, pid, t0):
    """Node `key`'s (RSS, threads) now: the first sample 3 s after t0 in first, the latest in last."""
    s = node_stats(pid)
    if s is None:
        return
    if key not in first and time.time() - t0 >= 3.0:
        first[key] = s
    if key in first:
        last[key] = s


def free_port():
    """A free loopback port (bound to port 0 and released)."""
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def orbit_verdict(peaks, t_end, nominal, fault):
    """live's orbit criterion on a plant summary's tilt_peaks [[t, alpha], ...]."""
    if fault:
        return "lost (fault)"
    last = peaks[-10:]
    since = t_end - peaks[-1][0] if peaks else t_end
    if since > 1.8:
        return f"lost (no tilt for {since:.1f} s)"
    if any(a[1] * b[1] >= 0 for a, b in zip(last, last[1:])):
        return "lost (tilts do not alternate)"
    if len(last) < 2:
        return "pending"
    mean = sum(abs(p[1]) for p in last) / len(last)
    off = 100.0 * (mean / nominal - 1.0)
    return "holds" if abs(off) <= 25.0 else f"lost ({off:+.0f} %)"


def plant_row(name, pl, nominal):
    steps = max(1, pl["steps"])
    return (name, pl["deadline_misses"], steps, pl["latency_us"]["p50"], pl["latency_us"]["p99"],
            pl["overruns"], pl["max_overrun_us"],
            orbit_verdict(pl["tilt_peaks"], pl["time"], nominal, pl.get("fault")))


def run_bare(args, n, form):
    """N robots as bare nodes: N process pairs (`pairs`) or one host pair (`host`)."""
    outdir = os.path.join(args.out, f"{form}{n}")
    os.makedirs(outdir, exist_ok=True)
    bindir = os.path.dirname(args.bin)
    plant_bin, ctl_bin = os.path.join(bindir, "tilting-plant"), os.path.join(bindir, "tilting-controller")
    names = [f"rb{n}x{i}_{os.getpid()}" for i in range(n)]
    common = ["--duration", str(args.duration), "--rate", str(args.rate)] + shlex.split(args.plant_args)
    groups = [names] if form == "host" else [[nm] for nm in names]
    # --fifo N: both nodes under SCHED_FIFO at N, every thread (as `tilting live --realtime N`).
    rt = ["chrt", "-f", str(args.fifo)] if args.fifo else []
    busy0, total0 = cpu_times()
    plants, ctls = [], []
    for g in groups:
        port = free_port()
        robot = ["--robots", ",".join(g)] if form == "host" else ["--robot", g[0]]
        tag = "host" if form == "host" else g[0]
        out = open(os.path.join(outdir, f"{tag}.plant.json"), "w")
        err = open(os.path.join(outdir, f"{tag}.plant.log"), "w")
        plants.append((tag, out.name, subprocess.Popen(
            rt + [plant_bin] + robot + ["--listen", f"tcp/127.0.0.1:{port}"] + common,
            stdout=out, stderr=err)))
        cerr = open(os.path.join(outdir, f"{tag}.controller.log"), "w")
        ctls.append((tag, subprocess.Popen(
            rt + [ctl_bin] + robot + ["--connect", f"tcp/127.0.0.1:{port}"],
            stdout=subprocess.DEVNULL, stderr=cerr)))
        time.sleep(args.stagger if form == "pairs" else 0.0)
    first, last = {}, {}
    t0 = time.time()
    nodes = [(tag, "tilting-plant", p) for tag, _, p in plants] + \
        [(tag, "tilting-controller", c) for tag, c in ctls]
    while any(p.poll() is None for _, _, p in plants):
        time.sleep(0.5)
        for tag, comm, p in nodes:
            sample(first, last, (tag, comm), p.pid, t0)
    busy1, total1 = cpu_times()
    for _, c in ctls:
        c.send_signal(2)
    for _, c in ctls:
        try:
            c.wait(10)
        except subprocess.TimeoutExpired:
            c.kill()
    cpu = 100.0 * (busy1 - busy0) / max(1, total1 - total0)
    rows = []
    for tag, path, p in plants:
        lines = [json.loads(l) for l in open(path) if l.strip().startswith("{")]
        if form == "host":
            got = {d["robot"]: d["summary"] for d in lines}
        else:
            got = {tag: lines[-1]} if lines else {}
        for name in ([tag] if form == "pairs" else names):
            if name in got:
                rows.append(plant_row(name, got[name], args.nominal_peak))
            else:
                rows.append((name, None, None, None, None, None, None,
                             f"no summary; exit {p.returncode}"))
    return rows, cpu, first, last, time.time() - t0


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
                sample(first, last, (name, comm), pid, t0)
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
    ap.add_argument("--fifo", type=int, default=0,
                    help="pairs and host forms: the nodes under SCHED_FIFO at this priority "
                         "(1 to 99; `chrt -f`, needs root; a quiet machine only); 0: off")
    ap.add_argument("--forms", default="live",
                    help="comma-separated forms, run alternately for each N: live, pairs, host")
    ap.add_argument("--plant-args", default="",
                    help="more flags for each bare tilting-plant (pairs, host), e.g. '--spin-us 0'")
    ap.add_argument("--nominal-peak", type=float, default=0.0413,
                    help="rad: the bare forms' orbit verdict compares the last tilts' mean |peak| with it")
    a = ap.parse_args()
    forms = a.forms.split(",")
    if not forms or any(f not in ("live", "pairs", "host") for f in forms):
        sys.exit(f"--forms: comma-separated live, pairs, host; got {a.forms}")
    ns = [int(x) for x in a.n.split(",")]
    if not all(1 <= n <= 32 for n in ns):
        sys.exit(f"--n: each count in [1, 32], got {a.n}")
    if not 1.0 <= a.duration <= 600.0:
        sys.exit(f"--duration: in [1, 600] s, got {a.duration}")
    if not 1.0 <= a.rate <= 10000.0:
        sys.exit(f"--rate: in [1, 10000] Hz, got {a.rate}")
    if not 0.0 <= a.stagger <= 5.0:
        sys.exit(f"--stagger: in [0, 5] s, got {a.stagger}")
    if not 0 <= a.fifo <= 99:
        sys.exit(f"--fifo: 0 (off) or a priority in [1, 99], got {a.fifo}")
    print(f"ZENOH_RUNTIME={os.environ.get('ZENOH_RUNTIME', '(default)')}; rate {a.rate} Hz; "
          f"{a.duration} s; {os.cpu_count()} cores")
    for n in ns:
        for form in forms:
            load = open("/proc/loadavg").read().split()[:3]
            if form == "live":
                rows, cpu, first, last, wall = run_n(a, n)
            else:
                rows, cpu, first, last, wall = run_bare(a, n, form)
            print(f"\nN = {n}, {form}: host CPU {cpu:.0f} % of all cores over {wall:.0f} s; "
                  f"load before {' '.join(load)}")
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
