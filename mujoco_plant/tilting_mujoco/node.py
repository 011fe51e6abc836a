"""The MuJoCo plant as a node of the tilting control loop: the topics, bytes and rules of
`tilting-plant` (docs/protocol.md), with MuJoCo in place of the hybrid model.

    python3 -m tilting_mujoco --duration 10                       # real time at 1 kHz
    python3 -m tilting_mujoco --clock lockstep --duration 10 --record run.csv
    tilting live --plant-cmd "python3 -m tilting_mujoco"          # in a live run

It takes the flags `tilting live` gives `tilting-plant` (session, ids, rate, duration, torque
limit, age rule, initial mode and state, parameters) and MuJoCo's own (`--preset`, `--solref`,
`--solimp`, `--friction`, `--timestep`). The loop:

- real time (`--clock realtime`, the default): state k goes out at `start + k h`; the main thread
  sleeps to the absolute deadline `start + (k + 1) h` (then busy-waits the last `--spin-us`),
  applies the newest torque at most `--max-age` periods old (the answer to k on time, else a
  deadline miss; none: the torque in force is held and the watchdog counts), steps MuJoCo over
  the period, publishes the period's mode events, then state k + 1; an overrun catches up
  without skipping periods;
- lockstep (`--clock lockstep`): after state k the plant waits for the answer to k (state
  re-published every 100 ms), then steps.

Safe mode after `--watchdog` periods without a torque (or at once when the controller's token
goes): a critically damped PD of the arm towards upright with gravity compensated. A model fault
(fall, contact loss, MuJoCo diverging: mjWARN_BADQACC and the other state warnings) ends the run
with status `faulted`, the reason in the status and summary, exit code 3. Bad flags: exit 1. At
the end one JSON summary on stdout, with the fields of the Rust plant's (`PlantSummary`).
"""

import argparse
import gc
import json
import math
import signal
import sys
import threading
import time

import numpy as np

from . import wire
from .model import FLAT, INTEGRATORS, LEFT, MODE_NAMES, PRESETS, RIGHT, Contact, Fault, MujocoPlant
from .params import Params

ORBIT_X0 = (0.0, math.pi / 2 - 0.000214877415, 0.0, 0.498257789692)


class Window:
    """The last 4096 samples of a figure in a numpy ring, and the largest of the whole run. Its
    percentiles (the Rust plant's rule: the sorted window's element at floor(q n)) take a
    partition in C: the status thread takes them 10 times a second, and sorting Python lists of
    4096 floats held the GIL for over a millisecond each time, delaying the loop."""

    SIZE = 4096

    def __init__(self):
        self.v = np.zeros(self.SIZE)
        self.n = 0
        self.largest = 0.0

    def add(self, x):
        self.v[self.n % self.SIZE] = x
        self.n += 1
        if x > self.largest:
            self.largest = x

    def percentiles(self, *qs):
        m = min(self.n, self.SIZE)
        if m == 0:
            return [0.0] * len(qs)
        idx = [min(m - 1, int(q * m)) for q in qs]
        part = np.partition(self.v[:m], idx)
        return [float(part[i]) for i in idx]

    def summary(self, count=False):
        p50, p99, p999 = self.percentiles(0.5, 0.99, 0.999)
        w = dict(p50=p50, p99=p99, max=self.largest)
        if count:
            w.update(p999=p999, count=self.n, window=self.SIZE)
        return w


class Node:
    """The plant node: the MuJoCo plant, the torque inbox and the counters (shared with zenoh's
    callback threads under one lock)."""

    def __init__(self, args, zenoh, sim):
        self.a, self.zenoh, self.sim = args, zenoh, sim
        self.prefix = f"tilting/{args.robot}"
        self.cv = threading.Condition()
        self.done = threading.Event()
        self.published_seq = -1  # newest state published
        self.t_pub = {}  # seq -> monotonic time of its first publication
        self.newest = None  # (seq, tau) of the newest valid torque received
        self.latency_us = Window()
        self.controller_alive = self.controller_seen = False
        expected = wire.id_bytes(args.controller_id) if args.controller_id else None
        lapse = args.lockstep_timeout_ms * 1e-3 if args.clock == "lockstep" else args.watchdog * args.period
        self.pin = wire.SourcePin(expected, lapse)
        self.c = dict(
            torques_received=0, torques_dropped=0, torques_stale=0, torques_foreign=0,
            torques_reordered=0, torques_late=0, torques_lost=0, torques_applied=0,
            deadline_misses=0, watchdog_trips=0, safe_periods=0, overruns=0,
        )
        self.jitter_us, self.step_us, self.age = Window(), Window(), Window()
        self.max_overrun = 0.0
        self.safe_modes = []
        self.state = wire.STARTING
        # (seq, time) of the newest state published: a status names that sample (one tuple, so
        # the status thread never pairs a seq with the time of a period stepped since).
        self.sample = (0, 0.0)
        self.fault = ""
        self.last_bad_log = 0.0

    # -- zenoh callbacks -----------------------------------------------------------------------

    def log_bad(self, msg):
        now = time.monotonic()
        if now - self.last_bad_log >= 1.0:
            self.last_bad_log = now
            print(f"tilting_mujoco: dropped a torque: {msg}", file=sys.stderr, flush=True)

    def on_torque(self, sample):
        now = time.monotonic()
        source = wire.source_of(sample)
        try:
            seq, tau = wire.unpack_torque(sample.payload.to_bytes())
            if abs(tau) > self.a.max_torque:
                raise ValueError(f"TorqueCommand.tau = {tau} exceeds --max-torque {self.a.max_torque} N m")
        except ValueError as e:
            with self.cv:
                self.c["torques_received"] += 1
                self.c["torques_dropped"] += 1
            self.log_bad(e)
            return
        with self.cv:
            self.c["torques_received"] += 1
            if not self.pin.admits(source, now):
                self.c["torques_foreign"] += 1
                return
            self.pin.believe(source, now)
            if seq > self.published_seq or (self.newest is not None and seq == self.newest[0]):
                self.c["torques_stale"] += 1
            elif self.newest is not None and seq < self.newest[0]:
                self.c["torques_reordered"] += 1
            else:
                self.newest = (seq, tau)
                t0 = self.t_pub.get(seq)
                if t0 is not None:
                    self.latency_us.add((now - t0) * 1e6)
                self.cv.notify_all()

    def on_controller_alive(self, sample):
        alive = sample.kind == self.zenoh.SampleKind.PUT
        with self.cv:
            self.controller_alive = alive
            self.controller_seen |= alive
            self.cv.notify_all()
        what = "appeared" if alive else "disappeared"
        print(f"tilting_mujoco: controller {what}", file=sys.stderr, flush=True)

    # -- publishing ----------------------------------------------------------------------------

    def status_bytes(self):
        with self.cv:
            c, state = dict(self.c), self.state
            lat = self.latency_us.percentiles(0.5, 0.99)
        jit, age = self.jitter_us.percentiles(0.5, 0.99), self.age.percentiles(0.5, 0.99)
        sim, (seq, t) = self.sim, self.sample
        return wire.pack_status(
            (
                seq, t, state, sim.mode, sim.tilts, seq,
                c["torques_received"], c["torques_dropped"], c["torques_stale"],
                c["deadline_misses"], c["watchdog_trips"],
                *jit, self.max_overrun, *lat,
                c["torques_late"], c["torques_lost"], c["torques_reordered"],
                *age, self.age.largest,
            ),
            self.fault,
        )

    def publish_state(self, seq):
        self.sample = (seq, self.sim.t)
        with self.cv:
            self.published_seq = max(self.published_seq, seq)
            self.t_pub.setdefault(seq, time.monotonic())
            self.t_pub.pop(seq - 64, None)
        self.pub_state.put(wire.pack_state(seq, self.sim.t, self.sim.mode, self.sim.x))

    def set_state(self, state):
        with self.cv:
            changed, self.state = self.state != state, state
        if changed:
            self.pub_status.put(self.status_bytes())

    def safe_torque(self):
        """Safe mode `hold`: beta_ddot = K_P (pi/2 - beta) - K_D beta_dot through the arm's
        inertia about its joint, gravity and viscous friction compensated; `zero`: none."""
        if self.a.safe_mode == "zero":
            return 0.0
        p = self.sim.p
        alpha, beta, _, bd = self.sim.x
        v = self.a.safe_kp * (math.pi / 2 - beta) - self.a.safe_kd * bd
        return p.joint_inertia() * v + p.m_l * p.g * p.lc * math.cos(alpha + beta) + p.b_v * bd

    # -- the loops -----------------------------------------------------------------------------

    def wait_for_controller(self):
        """State 0 every 100 ms until the controller's token appears or state 0 is answered."""
        while not self.done.is_set():
            self.publish_state(0)
            with self.cv:
                if self.controller_alive or self.newest is not None:
                    return
                self.cv.wait(0.1)
                if self.controller_alive or self.newest is not None:
                    return

    def choose_torque(self, k, tau_prev, safe):
        """The torque of period k by the age rule (real time), and whether it was fresh."""
        with self.cv:
            nw = self.newest
            gone = self.controller_seen and not self.controller_alive
        if nw is None or nw[0] != k:
            self.c["deadline_misses"] += 1
        if nw is not None and k - nw[0] <= self.a.max_age and not gone:
            seq, tau = nw
            if seq > self.last_applied:
                self.c["torques_lost"] += seq - self.last_applied - 1
                self.c["torques_applied"] += 1
                self.c["torques_late"] += seq < k
                self.last_applied = seq
            age = k - seq
            self.age.add(float(age))
            return tau, True
        return tau_prev, False

    def step(self, k, tau, t_next):
        t0 = time.perf_counter()
        try:
            events = self.sim.advance(tau, t_next)
        finally:
            for ev in self.sim.transitions:
                # A touch is dated back to its first step (model.py), maybe in period k - 1.
                seq = k if ev.t >= k * self.a.period else k - 1
                self.pub_event.put(wire.pack_event(seq, ev))
        cost = (time.perf_counter() - t0) * 1e6
        self.step_us.add(cost)
        return events

    def t_next(self, k):
        t = (k + 1) * self.a.period
        if self.a.duration is not None and t >= self.a.duration - 1e-9 * self.a.period:
            t = self.a.duration
        return t

    def enter_safe(self, k, cause):
        self.c["watchdog_trips"] += 1
        if len(self.safe_modes) < 100:
            self.safe_modes.append(dict(start=self.sim.t, end=None, cause=cause))
        print(f"tilting_mujoco: safe mode at seq {k}: {cause}", file=sys.stderr, flush=True)
        self.set_state(wire.SAFE)

    def leave_safe(self, k):
        if self.safe_modes and self.safe_modes[-1]["end"] is None:
            self.safe_modes[-1]["end"] = self.sim.t
        self.set_state(wire.RUNNING)

    def sleep_until(self, deadline, answer=None):
        """Sleeps to `deadline` on the monotonic clock, the last --spin-us busy (yielding the
        GIL, so a torque arriving then is taken at once). With `answer` (a seq) it returns as
        soon as the torque answering it is in. Returns whether that torque is in."""
        spin = self.a.spin_us * 1e-6
        while not self.done.is_set():
            now = time.monotonic()
            with self.cv:
                if answer is not None and self.newest is not None and self.newest[0] >= answer:
                    return True
                if deadline - now > spin:
                    self.cv.wait(deadline - now - spin) if answer is not None else None
            if deadline - now > spin:
                if answer is None:
                    time.sleep(deadline - now - spin)
                continue
            if now >= deadline:
                return False
            time.sleep(0)
        return False

    def run_realtime(self, n, record):
        """State k goes out at the deadline start + k h. Period k is integrated as soon as the
        answer to k is in (so the integration does not eat into the controller's period), else
        at the deadline start + (k + 1) h with the torque the age rule gives: the same
        computation as integrating at the deadline, since the answer to k is the newest torque
        there can be. Then state k + 1 goes out at its deadline."""
        a, h = self.a, self.a.period
        tau, safe, silent = 0.0, False, 0
        self.last_applied = -1
        start = time.monotonic()
        k = 0
        self.publish_state(0)
        while not self.done.is_set() and k < n:
            deadline = start + (k + 1) * h
            self.sleep_until(deadline, answer=k)
            tau_new, fresh = self.choose_torque(k, tau, safe)
            if fresh:
                tau, silent = tau_new, 0
                if safe:
                    safe = False
                    self.leave_safe(k)
            else:
                silent += 1
                with self.cv:
                    gone = self.controller_seen and not self.controller_alive
                if not safe and (silent >= a.watchdog or gone):
                    safe = True
                    why = "the controller's liveliness token disappeared" if gone else (
                        f"no torque for {a.watchdog} periods (watchdog)")
                    self.enter_safe(k, why)
            applied = self.safe_torque() if safe else tau
            if safe:
                self.c["safe_periods"] += 1
            applied = max(-a.torque_limit, min(a.torque_limit, applied))
            if record:
                record.write(f"{k},{self.sim.t!r},{self.sim.mode},{','.join(map(repr, self.sim.x))},{applied!r}\n")
            self.step(k, applied, self.t_next(k))
            k += 1
            late = time.monotonic() - (start + (k + 1) * h)
            if late > 0:  # the step ended after the next deadline (as the Rust plant counts)
                self.c["overruns"] += 1
                self.max_overrun = max(self.max_overrun, late * 1e6)
            self.sleep_until(deadline)
            self.jitter_us.add((time.monotonic() - deadline) * 1e6)
            self.publish_state(k)
        return k

    def wait_for_answer(self, seq, safe):
        timeout = 1e-3 if safe else self.a.lockstep_timeout_ms * 1e-3
        now = time.monotonic()
        end, repub = now + timeout, now + 0.1
        with self.cv:
            while True:
                if self.newest is not None and self.newest[0] == seq:
                    return self.newest[1]
                if self.done.is_set() or (self.controller_seen and not self.controller_alive):
                    return None
                now = time.monotonic()
                if now >= end:
                    return None
                if now >= repub:
                    self.cv.release()
                    try:
                        self.pub_state.put(wire.pack_state(seq, self.sim.t, self.sim.mode, self.sim.x))
                    finally:
                        self.cv.acquire()
                    repub = now + 0.1
                self.cv.wait(min(end, repub) - now)

    def through_link(self, k, answer):
        """Lockstep over an emulated link of `--delay` s each way: the answer to state k
        arrives at t_k + 2 delay and is in force from the first period starting then (within
        1e-9 periods), the newest arrived answer at most `--max-age` periods old; until the
        first arrives the torque is 0. The rule of the Rust plant's lockstep hold
        (`tilting_link::ImpairedHold`) for a fixed delay, so a run over a 50 ms round trip is
        deterministic and does not depend on the machine's load. Without `--delay`: `answer`."""
        a = self.a
        if not a.delay:
            self.c["torques_applied"] += 1
            self.age.add(0.0)
            return answer
        h = a.period
        self.flight.append((k, k * h + 2.0 * a.delay, answer))
        t_k, tol = k * h, 1e-9 * h
        best = None
        keep = []
        for f in self.flight:
            if f[1] > t_k + tol:
                keep.append(f)
            elif k - f[0] <= a.max_age and (best is None or f[0] > best[0]):
                best = f
        self.flight = keep
        if best is not None:
            self.c["torques_applied"] += 1
            self.c["torques_late"] += best[0] < k
            self.age.add(float(k - best[0]))
            self.link_tau = best[2]
        return self.link_tau

    def run_lockstep(self, n, record):
        a = self.a
        k, safe = 0, False
        self.last_applied = -1
        self.flight, self.link_tau = [], 0.0
        while not self.done.is_set() and k < n:
            if k > 0:
                self.publish_state(k)
            tau = self.wait_for_answer(k, safe)
            if self.done.is_set():
                break
            if tau is None:
                self.c["deadline_misses"] += 1
                if not safe:
                    safe = True
                    self.enter_safe(k, "lockstep timeout or the controller's token gone")
                tau = self.safe_torque()
                self.c["safe_periods"] += 1
            else:
                if safe:
                    safe = False
                    self.leave_safe(k)
                tau = self.through_link(k, tau)
            tau = max(-a.torque_limit, min(a.torque_limit, tau))
            if record:
                record.write(f"{k},{self.sim.t!r},{self.sim.mode},{','.join(map(repr, self.sim.x))},{tau!r}\n")
            self.step(k, tau, self.t_next(k))
            k += 1
        if k >= n and not self.done.is_set():
            self.publish_state(k)
        return k

    def run(self):
        z, a = self.zenoh, self.a
        cfg = wire.session_config(z, a.listen, a.connect, a.zenoh_config)
        if a.zenoh_id:
            cfg.insert_json5("id", json.dumps(a.zenoh_id))
        session = z.open(cfg)
        rt = dict(congestion_control=z.CongestionControl.DROP, priority=z.Priority.REAL_TIME)
        if a.clock == "lockstep":
            rt["congestion_control"] = z.CongestionControl.BLOCK
        data = dict(congestion_control=z.CongestionControl.DROP, priority=z.Priority.DATA)
        pub = wire.SourcedPublisher
        self.pub_state = pub(session, f"{self.prefix}/plant/state", express=True, **rt)
        self.pub_event = pub(session, f"{self.prefix}/plant/event", **data)
        self.pub_status = pub(session, f"{self.prefix}/plant/status", **data)
        sub = session.declare_subscriber(f"{self.prefix}/controller/torque", self.on_torque)
        watch = session.liveliness().declare_subscriber(
            f"{self.prefix}/alive/controller", self.on_controller_alive, history=True
        )
        token = session.liveliness().declare_token(f"{self.prefix}/alive/plant")
        c = self.sim.contact
        print(
            f"tilting_mujoco: robot {a.robot}, {a.clock}, period {a.period} s, duration {a.duration} s; "
            f"MuJoCo step {c.timestep} s, solref {c.solref}, solimp {c.solimp}, friction {c.friction}; "
            f"listen {a.listen}, connect {a.connect}",
            file=sys.stderr, flush=True,
        )
        record = open(a.record, "w", encoding="utf-8") if a.record else None
        if record:
            record.write("seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau\n")
        status_stop = threading.Event()

        def status_loop():  # 10 Hz
            while not status_stop.wait(0.1):
                self.pub_status.put(self.status_bytes())

        threading.Thread(target=status_loop, daemon=True).start()
        self.pub_status.put(self.status_bytes())
        n = math.inf if a.duration is None else round(a.duration / a.period)
        result, code, k = "stopped", 0, 0
        try:
            if not a.no_wait:
                self.wait_for_controller()
            with self.cv:  # the wait for the controller is not loop latency
                self.t_pub.pop(0, None)
            self.set_state(wire.RUNNING)
            loop = self.run_lockstep if a.clock == "lockstep" else self.run_realtime
            try:
                k = loop(n, record)
                if k >= n:
                    result = "completed"
            except Fault as f:
                self.fault = str(f)
                print(f"tilting_mujoco: fault: {f}", file=sys.stderr, flush=True)
                result, code = "faulted", 3
            k = max(k, self.published_seq)
        finally:
            if record:
                if result == "completed":
                    record.write(f"{k},{self.sim.t!r},{self.sim.mode},{','.join(map(repr, self.sim.x))},\n")
                record.close()
            status_stop.set()
            self.set_state(wire.FAULTED if code == 3 else wire.STOPPED)
            self.pub_status.put(self.status_bytes())
            time.sleep(0.05)  # let the last messages leave
            token.undeclare()
            watch.undeclare()
            sub.undeclare()
            for p in (self.pub_state, self.pub_event, self.pub_status):
                p.undeclare()
            session.close()
        print(json.dumps(self.summary(result, k)), flush=True)
        return code

    def summary(self, result, k):
        sim, a = self.sim, self.a
        with self.cv:
            c = dict(self.c)
            lat = self.latency_us.summary(count=True)
        c_ = sim.contact
        return dict(
            result=result,
            fault=self.fault or None,
            clock=a.clock,
            period=a.period,
            seq=k,
            time=sim.t,
            mode=MODE_NAMES[sim.mode],
            x=list(sim.x),
            steps=k,
            tilts=sim.tilts,
            transitions=sim.n_transitions,
            **c,
            age_periods=self.age.summary(),
            safe_modes=self.safe_modes,
            max_overrun_us=self.max_overrun,
            jitter_us=self.jitter_us.summary(),
            latency_us=lat,
            step_us=self.step_us.summary(),
            tilt_peaks=[list(p) for p in sim.peaks.all(sim.t, sim.x[0])[-256:]],
            engine=dict(
                name="mujoco",
                version=__import__("mujoco").__version__,
                timestep=c_.timestep,
                solref=list(c_.solref),
                solimp=list(c_.solimp),
                friction=c_.friction,
                plate_inertia=sim.p.plate_inertia(),
                airborne_steps=sim.airborne_steps,
            ),
        )


# -- the command line --------------------------------------------------------------------------


class ArgumentParser(argparse.ArgumentParser):
    """Bad arguments exit with 1, as `tilting-plant` does."""

    def error(self, message):
        self.print_usage(sys.stderr)
        if message.startswith("unrecognized arguments"):
            message += (
                " (of tilting-plant's flags for an emulated link only --delay, in lockstep, is "
                "this plant's; imperfect sensors and ROS 2 are not: MuJoCo gives the true state, "
                "docs/mujoco.md)"
            )
        self.exit(1, f"{self.prog}: error: {message}\n")


def floats(n):
    def parse(text):
        try:
            v = tuple(float(s) for s in text.split(","))
        except ValueError:
            v = ()
        if len(v) != n or not all(math.isfinite(u) for u in v):
            raise argparse.ArgumentTypeError(f"expected {n} finite numbers separated by commas")
        return v

    return parse


def parser():
    ap = ArgumentParser(prog="python3 -m tilting_mujoco", description="The tilting robot in MuJoCo as a plant node (docs/mujoco.md).")
    ap.add_argument("--robot", default="demo", help="key prefix tilting/{robot}/... (default demo)")
    ap.add_argument("--listen", action="append", help="endpoint, repeatable (default tcp/127.0.0.1:7447)")
    ap.add_argument("--connect", action="append", help="endpoint, repeatable (default none)")
    ap.add_argument("--zenoh-config", help="a zenoh configuration file (JSON5), e.g. the certificates' of --secure")
    ap.add_argument("--zenoh-id", type=wire.zenoh_id_arg, help="this session's zenoh id")
    ap.add_argument("--controller-id", type=wire.zenoh_id_arg, help="believe torques only from this session")
    ap.add_argument("--clock", choices=["realtime", "lockstep"], default="realtime")
    ap.add_argument("--rate", type=float, help="control rate, Hz (default 1000)")
    ap.add_argument("--period", type=float, help="control period, s (default 0.001)")
    ap.add_argument("--duration", type=float, help="plant time to run, s (default: until Ctrl-C)")
    ap.add_argument("--max-age", type=int, default=10, help="apply torques at most this many periods old (default 10)")
    ap.add_argument("--watchdog", type=int, default=50, help="periods without a torque before safe mode (default 50)")
    ap.add_argument("--safe-mode", choices=["zero", "hold"], default="hold")
    ap.add_argument("--safe-kp", type=float, default=25.0)
    ap.add_argument("--safe-kd", type=float, default=10.0)
    ap.add_argument("--lockstep-timeout-ms", type=float, default=1000.0)
    ap.add_argument(
        "--delay", type=float, default=0.0,
        help="lockstep only: an emulated link delaying states and torques this many seconds each "
        "way, as tilting-plant's --delay (0 to 1; the answer to state k is in force from "
        "t_k + 2 delay), deterministic",
    )
    ap.add_argument(
        "--seed", type=int, default=0,
        help="accepted and ignored: `tilting live --delay` passes its link's seed, and a fixed "
        "delay draws nothing",
    )
    ap.add_argument("--mode", choices=["flat", "left", "right"], default="left")
    ap.add_argument("--x0", type=floats(4), help="initial alpha,beta,alpha_dot,beta_dot (default the paper's orbit start)")
    ap.add_argument("--params", help="TOML with the keys of docs/model.md (default the paper's robot)")
    ap.add_argument("--impact", help="accepted and ignored: in MuJoCo the contact decides a landing")
    ap.add_argument("--max-torque", type=float, default=116.5, help="refuse |tau| above, N m (default 116.5)")
    ap.add_argument("--torque-limit", type=float, default=math.inf, help="saturate the applied torque, N m")
    ap.add_argument("--record", help="CSV of every sample: seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau")
    ap.add_argument("--no-wait", action="store_true", help="start without waiting for a controller")
    ap.add_argument("--spin-us", type=float, default=100.0, help="busy-wait before each deadline, us (default 100)")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="stiff", help="contact settings (default stiff)")
    ap.add_argument("--solref", type=floats(2), help="MuJoCo solref TIMECONST,DAMPRATIO (overrides the preset's)")
    ap.add_argument("--solimp", type=floats(5), help="MuJoCo solimp D0,DWIDTH,WIDTH,MID,POWER (overrides the preset's)")
    ap.add_argument("--friction", type=float, help="sliding friction coefficient (overrides the preset's; >= 0.3)")
    ap.add_argument("--timestep", type=float, help="MuJoCo time step, s (overrides the preset's 2e-4)")
    ap.add_argument("--integrator", choices=INTEGRATORS, help="MuJoCo's integrator (overrides the preset's RK4)")
    ap.add_argument("--print-mjcf", action="store_true", help="print the MJCF and exit")
    ap.add_argument("--self-test", action="store_true", help="run the physical checks (no zenoh) and exit")
    return ap


def contact_of(args):
    c = PRESETS[args.preset]
    return Contact(
        solref=args.solref or c.solref,
        solimp=args.solimp or c.solimp,
        friction=c.friction if args.friction is None else args.friction,
        timestep=args.timestep or c.timestep,
        integrator=args.integrator or c.integrator,
    )


def main(argv=None):
    ap = parser()
    a = ap.parse_args(argv)
    if a.self_test:
        from . import checks

        return checks.main()
    if a.rate is not None and a.period is not None:
        ap.error("--rate and --period: give one")
    a.period = 1.0 / a.rate if a.rate else (a.period or 1e-3)
    if not (1e-4 <= a.period <= 10.0):
        ap.error(f"--period {a.period}: allowed 1e-4 to 10 s (--rate 0.1 to 10000 Hz)")
    if a.duration is not None and not (0.0 < a.duration and a.duration / a.period <= 1e9):
        ap.error(f"--duration {a.duration}: allowed > 0 and at most 1e9 periods")
    if not wire.ROBOT_RE.match(a.robot):
        ap.error(f"--robot {a.robot!r}: allowed characters are [A-Za-z0-9_-], non-empty")
    if not (0 <= a.max_age <= 1000) or not (1 <= a.watchdog <= 1_000_000):
        ap.error("--max-age: allowed 0 to 1000 periods; --watchdog: 1 to 1,000,000")
    if not (0.0 <= a.delay <= 1.0):
        ap.error(f"--delay {a.delay}: allowed 0 to 1 s")
    if a.delay and a.clock != "lockstep":
        ap.error(
            f"--delay {a.delay}: only with --clock lockstep (in real time, delay the messages on "
            "the network: bench/delay_plant.py or a network namespace, docs/mujoco.md)"
        )
    if not (a.torque_limit > 0):
        ap.error(f"--torque-limit {a.torque_limit}: allowed > 0")
    a.listen = a.listen or ([] if a.zenoh_config else ["tcp/127.0.0.1:7447"])
    a.connect = a.connect or []
    try:
        params = Params.from_toml(a.params) if a.params else Params()
        contact = contact_of(a)
        mode = {"flat": FLAT, "left": LEFT, "right": RIGHT}[a.mode]
        x0 = a.x0 or (ORBIT_X0 if a.mode != "flat" else (0.0, math.pi / 2, 0.0, 0.0))
        contact.check()
        if a.print_mjcf:
            from .model import mjcf

            print(mjcf(params, contact))
            return 0
        if contact.timestep > a.period:
            raise ValueError(f"--timestep {contact.timestep}: at most the control period {a.period} s")
        sim = MujocoPlant(params, contact, mode, x0)
    except (ValueError, OSError) as e:
        ap.error(str(e))
    except Fault as e:
        print(f"tilting_mujoco: fault at the start: {e}", file=sys.stderr)
        return 3
    import zenoh  # here, so that --self-test and --print-mjcf run without it

    node = Node(a, zenoh, sim)

    def stop(_signum, _frame):
        node.done.set()
        with node.cv:
            node.cv.notify_all()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    # zenoh's callback threads wait for the GIL: hand it over within 0.1 ms, not 5 ms. And what
    # exists now (MuJoCo, zenoh, numpy) is never scanned by a full garbage collection.
    sys.setswitchinterval(1e-4)
    gc.collect()
    gc.freeze()
    return node.run()
