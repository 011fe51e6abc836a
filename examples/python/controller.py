#!/usr/bin/env python3
"""A stand-alone tilting-system controller in pure Python, speaking the wire protocol of
docs/protocol.md over zenoh: a drop-in replacement for `tilting-controller`.

It shares no code with the Rust workspace: the byte layouts are Python `struct` formats and the
control law (computed torque per contact mode, PD on the arm angle, energy adaptation of the
stiffness) is written here from the model notes (docs/model.md), so a plant run against this script
checks that the protocol is language-neutral.

For every valid `PlantState` on `tilting/{robot}/plant/state` it publishes a `TorqueCommand` with
the same `seq` on `tilting/{robot}/controller/torque`, and it declares the liveliness token
`tilting/{robot}/alive/controller` (after its subscriber and publisher, as the protocol asks).
The reference is `beta_d = pi/2` (hold); this script does not listen to the planner.

    python3 controller.py --connect tcp/127.0.0.1:7447 --robot demo

`--self-test` checks the encodings against the worked examples of docs/protocol.md and the law
against the equations of motion, without zenoh. At Ctrl-C/SIGTERM it prints a JSON object of
its counters on stdout and exits 0.
"""

import argparse
import json
import math
import re
import signal
import struct
import sys
import threading
import time

import tilting_source

# ---------------------------------------------------------------------------------------------
# Wire format (docs/protocol.md): little-endian, no padding, no header.

# Protocol 2: seq, time, alpha, beta, alpha_dot, beta_dot, mode, measured (bit 0 alpha, 1 beta,
# 2 alpha_dot, 3 beta_dot); an absent rate has its bit clear and +0.0 in its slot.
PLANT_STATE = struct.Struct("<Q5d2B")
TORQUE = struct.Struct("<Qd")  # seq, tau
assert PLANT_STATE.size == 50 and TORQUE.size == 16
MEASURED_ALL = 15
# How long the plant's pinned session may be silent before another may take the pin (s), when
# no --plant-id was given: the Rust controller's.
PIN_LAPSE = 0.5

FLAT, LEFT, RIGHT = 0, 1, 2


def unpack_plant_state(payload):
    """Decodes and validates a PlantState with every field measured; raises ValueError naming
    the problem. This controller has no estimator: a state without rates (`--measure angles`)
    is refused, never read with zero rates."""
    if len(payload) == 49:
        raise ValueError(
            "PlantState: a 49-byte payload is protocol 1 (no `measured` byte); this peer speaks "
            "protocol 2 (50 bytes): update the sender"
        )
    if len(payload) != PLANT_STATE.size:
        raise ValueError(
            f"PlantState: wrong payload size: expected {PLANT_STATE.size} bytes, got {len(payload)}"
        )
    seq, t, alpha, beta, alpha_dot, beta_dot, mode, measured = PLANT_STATE.unpack(payload)
    if measured != MEASURED_ALL:
        raise ValueError(
            f"PlantState.measured = {measured}: this controller needs every field measured (15); "
            "run the plant with --measure full or use tilting-controller, which estimates the rates"
        )
    for name, v in (
        ("time", t),
        ("alpha", alpha),
        ("beta", beta),
        ("alpha_dot", alpha_dot),
        ("beta_dot", beta_dot),
    ):
        if not math.isfinite(v):
            raise ValueError(f"PlantState.{name} = {v} is not finite")
    if mode > 2:
        raise ValueError(f"PlantState.mode = {mode} is out of range; allowed: 0..=2")
    return seq, t, (alpha, beta, alpha_dot, beta_dot), mode


def pack_torque(seq, tau):
    """Encodes a TorqueCommand; refuses a non-finite torque."""
    if not math.isfinite(tau):
        raise ValueError(f"TorqueCommand.tau = {tau} is not finite")
    return TORQUE.pack(seq, tau)


# ---------------------------------------------------------------------------------------------
# Model (docs/model.md): plate of length 2f with a point mass m_f at its centre, arm of length l with
# a point mass m_l at its tip, mounted on the plate centre. World origin at the left plate edge,
# y up. Tilted left: pivot (0, 0); tilted right: pivot (2f, 0), the same equations with f -> -f.


class Params:
    def __init__(self, m_f=1.0, m_l=1.0, l=2.0, f=0.5, g=9.81):
        self.m_f, self.m_l, self.l, self.f, self.g = m_f, m_l, l, f, g

    def signed_f(self, mode):
        """+f seen from the left pivot (and flat: the origin is the left edge), -f from the right."""
        return -self.f if mode == RIGHT else self.f


def mass_matrix(p, mode, beta):
    """(M11, M12, M22) of the tilted double pendulum about the pivot."""
    sf = p.signed_f(mode)
    cb = math.cos(beta)
    m11 = p.m_f * sf**2 + p.m_l * (sf**2 + 2.0 * sf * p.l * cb + p.l**2)
    m12 = p.m_l * p.l * (p.l + sf * cb)
    m22 = p.m_l * p.l**2
    return m11, m12, m22


def bias(p, mode, x):
    """(h1, h2): Coriolis, centrifugal and gravity terms of the tilted equations."""
    alpha, beta, ad, bd = x
    sf = p.signed_f(mode)
    sb = math.sin(beta)
    cab = math.cos(alpha + beta)
    h1 = (
        -p.m_l * sf * p.l * sb * (2.0 * ad * bd + bd**2)
        + (p.m_f + p.m_l) * p.g * sf * math.cos(alpha)
        + p.m_l * p.g * p.l * cab
    )
    h2 = p.m_l * p.l * (sf * sb * ad**2 + p.g * cab)
    return h1, h2


def torque_for_beta_ddot(p, mode, x, v):
    """Computed torque: the joint torque that makes beta_ddot = v in `mode`."""
    alpha, beta, _, _ = x
    if mode == FLAT:
        # One degree of freedom: tau = m_l l (l beta_ddot + g cos beta).
        return p.m_l * p.l * (p.l * v + p.g * math.cos(beta))
    m11, m12, m22 = mass_matrix(p, mode, beta)
    h1, h2 = bias(p, mode, x)
    # Row 1 (unactuated): M11 alpha_ddot + M12 v + h1 = 0.
    alpha_ddot = -(m12 * v + h1) / m11
    # Row 2: tau = M21 alpha_ddot + M22 v + h2.
    return m12 * alpha_ddot + m22 * v + h2


def accelerations(p, mode, x, tau):
    """Forward dynamics (alpha_ddot, beta_ddot) under torque tau (used by --self-test)."""
    alpha, beta, _, _ = x
    if mode == FLAT:
        return 0.0, (tau / (p.m_l * p.l) - p.g * math.cos(beta)) / p.l
    m11, m12, m22 = mass_matrix(p, mode, beta)
    h1, h2 = bias(p, mode, x)
    det = m11 * m22 - m12 * m12
    return (m22 * -h1 - m12 * (tau - h2)) / det, (m11 * (tau - h2) + m12 * h1) / det


def energy(p, mode, x):
    """E = T + V from the positions and velocities of the two point masses (ground at y = 0)."""
    alpha, beta, ad, bd = x
    sf = p.signed_f(mode)
    sa, ca = math.sin(alpha), math.cos(alpha)
    sab, cab = math.sin(alpha + beta), math.cos(alpha + beta)
    # Plate centre relative to the pivot: sf (cos a, sin a); arm tip: + l (cos(a+b), sin(a+b)).
    y_f = sf * sa
    y_l = y_f + p.l * sab
    vf = (-sf * ad * sa, sf * ad * ca)
    vl = (vf[0] - p.l * (ad + bd) * sab, vf[1] + p.l * (ad + bd) * cab)
    kinetic = 0.5 * (p.m_f * (vf[0] ** 2 + vf[1] ** 2) + p.m_l * (vl[0] ** 2 + vl[1] ** 2))
    potential = p.g * (p.m_f * y_f + p.m_l * y_l)
    return kinetic + potential


class ComputedTorquePD:
    """v = beta_d_ddot + K_D (beta_d_dot - beta_dot) + K_P (beta_d - beta), beta_d = pi/2 (hold),
    with K_P = K_P0 + k (E_av - E(x)); tau = the computed torque of the current mode for v."""

    def __init__(self, kp=100.0, kd=14.14, k=0.0, energy_avg=0.0, params=None):
        if not all(math.isfinite(g) and g >= 0.0 for g in (kp, kd, k)):
            raise ValueError("kp, kd and k must be finite and >= 0")
        if not math.isfinite(energy_avg) or (k > 0.0 and energy_avg <= 0.0):
            raise ValueError("energy_avg must be > 0 (the orbit's average energy, J) when k > 0")
        self.kp, self.kd, self.k, self.energy_avg = kp, kd, k, energy_avg
        self.p = params or Params()

    def stiffness(self, mode, x):
        if self.k == 0.0:
            return self.kp
        return self.kp + self.k * (self.energy_avg - energy(self.p, mode, x))

    def acceleration(self, mode, x):
        beta_d, beta_d_dot, beta_d_ddot = math.pi / 2.0, 0.0, 0.0
        return (
            beta_d_ddot
            + self.kd * (beta_d_dot - x[3])
            + self.stiffness(mode, x) * (beta_d - x[1])
        )

    def torque(self, mode, x):
        return torque_for_beta_ddot(self.p, mode, x, self.acceleration(mode, x))


# ---------------------------------------------------------------------------------------------
# Self-test: no zenoh needed.


def self_test():
    state = PLANT_STATE.pack(42, 1.5, 0.25, math.pi / 2, -0.5, 2.0, 1, MEASURED_ALL)
    assert state.hex() == (
        "2a00000000000000000000000000f83f000000000000d03f182d4454fb21f93f"
        "000000000000e0bf0000000000000040010f"
    ), state.hex()
    assert unpack_plant_state(state) == (42, 1.5, (0.25, math.pi / 2, -0.5, 2.0), 1)
    assert pack_torque(42, -0.125).hex() == "2a00000000000000000000000000c0bf"
    angles_only = state[:32] + bytes(16) + state[48:49] + b"\x03"
    for bad in (
        state[:-1],
        state[:-2] + b"\x03\x0f",
        state[:16] + struct.pack("<d", math.nan) + state[24:],
        angles_only,
    ):
        try:
            unpack_plant_state(bad)
        except ValueError:
            pass
        else:
            raise AssertionError(f"accepted {bad.hex()}")
    p = Params()
    c = ComputedTorquePD(k=300.0, energy_avg=20.0)
    for mode, x in (
        (FLAT, (0.0, 1.3, 0.0, 0.4)),
        (LEFT, (0.1, 1.7, -0.3, 0.2)),
        (RIGHT, (-0.2, 1.4, 0.5, -0.6)),
    ):
        v = c.acceleration(mode, x)
        _, bdd = accelerations(p, mode, x, c.torque(mode, x))
        assert abs(bdd - v) < 1e-9 * (1.0 + abs(v)), (mode, bdd, v)
    # Energy against the mass matrix: T = 1/2 qdot^T M qdot, V = g ((m_f + m_l) sf sin a + m_l l sin(a+b)).
    for mode, x in ((LEFT, (0.1, 1.7, -0.3, 0.2)), (RIGHT, (-0.2, 1.4, 0.5, -0.6))):
        m11, m12, m22 = mass_matrix(p, mode, x[1])
        sf = p.signed_f(mode)
        e = 0.5 * (m11 * x[2] ** 2 + 2 * m12 * x[2] * x[3] + m22 * x[3] ** 2) + p.g * (
            (p.m_f + p.m_l) * sf * math.sin(x[0]) + p.m_l * p.l * math.sin(x[0] + x[1])
        )
        assert abs(e - energy(p, mode, x)) < 1e-12 * abs(e), (mode, e, energy(p, mode, x))
    # Mirror symmetry: (alpha, beta) -> (-alpha, pi - beta) maps left onto right, torque negated.
    x = (0.1, 1.7, -0.3, 0.2)
    xm = (-x[0], math.pi - x[1], -x[2], -x[3])
    a, b = c.torque(LEFT, x), c.torque(RIGHT, xm)
    assert abs(a + b) < 1e-9 * (1.0 + abs(a)), (a, b)
    print("self-test passed")


# ---------------------------------------------------------------------------------------------
# The zenoh node.

ROBOT_RE = re.compile(r"^[A-Za-z0-9_-]+$")


def session_config(zenoh, listen, connect):
    """The session of docs/protocol.md: peer mode, multicast scouting off, gossip on, explicit
    loopback endpoints, connect retry 100 ms doubling to 1 s."""
    cfg = zenoh.Config()
    for key, value in (
        ("mode", '"peer"'),
        ("scouting/multicast/enabled", "false"),
        ("scouting/gossip/enabled", "true"),
        ("scouting/delay", "1000"),
        ("timestamping/enabled", "false"),
        ("connect/retry", "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}"),
        ("listen/endpoints", json.dumps(listen)),
        ("connect/endpoints", json.dumps(connect)),
        # A link whose peer stops reading drops loop messages instead of stalling the loop.
        ("transport/link/tx/queue/size/real_time", "16"),
        ("transport/link/tx/queue/congestion_control/drop/wait_before_drop", "50"),
    ):
        cfg.insert_json5(key, value)
    return cfg


class RateLimitedLog:
    """The first problem in full, then at most one line per second with the count suppressed."""

    def __init__(self, what):
        self.what, self.last, self.suppressed = what, None, 0

    def __call__(self, msg):
        now = time.monotonic()
        if self.last is None or now - self.last >= 1.0:
            extra = f" ({self.suppressed} more suppressed)" if self.suppressed else ""
            print(f"controller.py: dropped {self.what}: {msg}{extra}", file=sys.stderr, flush=True)
            self.last, self.suppressed = now, 0
        else:
            self.suppressed += 1


def run(args):
    import zenoh  # imported here so that --self-test runs without it

    if not ROBOT_RE.match(args.robot):
        raise SystemExit(f"--robot {args.robot!r}: allowed characters are [A-Za-z0-9_-], non-empty")
    law = ComputedTorquePD(kp=args.kp, kd=args.kd, k=args.k, energy_avg=args.energy_avg)
    prefix = f"tilting/{args.robot}"
    counters = {
        "states_received": 0,
        "states_dropped": 0,
        "torques_published": 0,
        "torques_not_finite": 0,
        "states_foreign": 0,
    }
    # --plant-id: states are believed only from that session; without it, from the session of
    # the first state believed, until it is silent for 0.5 s (docs/protocol.md, as the Rust
    # controller).
    plant_id = tilting_source.id_bytes(args.plant_id) if args.plant_id else None
    pin = tilting_source.SourcePin(plant_id, lapse=PIN_LAPSE)
    lock = threading.Lock()
    log_bad = RateLimitedLog(f"{prefix}/plant/state")
    done = threading.Event()

    cfg = session_config(zenoh, args.listen, args.connect)
    if args.zenoh_id:
        cfg.insert_json5("id", json.dumps(args.zenoh_id))
    session = zenoh.open(cfg)
    # Every put names this session (the TSRC attachment of docs/protocol.md).
    publisher = tilting_source.SourcedPublisher(
        session,
        f"{prefix}/controller/torque",
        # Dropped on a link whose peer stops reading, never waited for (docs/protocol.md).
        congestion_control=zenoh.CongestionControl.DROP,
        priority=zenoh.Priority.REAL_TIME,
        express=True,
    )

    def on_state(sample):
        source, now = tilting_source.source_of(sample), time.monotonic()
        with lock:
            admitted = pin.admits(source, now)
            if not admitted:
                counters["states_received"] += 1
                counters["states_foreign"] += 1
                pinned = tilting_source.id_text(pin.pinned)
        if not admitted:
            log_bad(f"PlantState from a foreign source, not the plant's session {pinned}")
            return
        try:
            seq, _t, x, mode = unpack_plant_state(sample.payload.to_bytes())
        except ValueError as e:
            with lock:
                counters["states_received"] += 1
                counters["states_dropped"] += 1
            log_bad(e)
            return
        with lock:
            pin.believe(source, now)
        tau = law.torque(mode, x)
        with lock:
            counters["states_received"] += 1
            if not math.isfinite(tau):
                counters["torques_not_finite"] += 1
                return
            counters["torques_published"] += 1
        publisher.put(pack_torque(seq, tau))

    def on_plant_alive(sample):
        what = "appeared" if sample.kind == zenoh.SampleKind.PUT else "disappeared"
        print(f"controller.py: plant {what} ({sample.key_expr})", file=sys.stderr, flush=True)

    subscriber = session.declare_subscriber(f"{prefix}/plant/state", on_state)
    plant_watch = session.liveliness().declare_subscriber(
        f"{prefix}/alive/plant", on_plant_alive, history=True
    )
    # Declared last: a plant that sees the token can talk to us at once.
    token = session.liveliness().declare_token(f"{prefix}/alive/controller")
    print(
        f"controller.py: robot {args.robot}, K_P0 {law.kp}, K_D {law.kd}, k {law.k}, "
        f"E_av {law.energy_avg} J; connect {args.connect}",
        file=sys.stderr,
        flush=True,
    )

    def stop(_signum, _frame):
        done.set()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    while not done.wait(0.2):
        pass
    token.undeclare()
    plant_watch.undeclare()
    subscriber.undeclare()
    publisher.undeclare()
    session.close()
    with lock:
        summary = dict(counters)
    summary["law"] = {"kp": law.kp, "kd": law.kd, "k": law.k, "energy_avg": law.energy_avg}
    print(json.dumps(summary), flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="demo", help="key prefix tilting/{robot}/... (default demo)")
    ap.add_argument(
        "--connect",
        action="append",
        help="zenoh endpoint to connect to, repeatable (default tcp/127.0.0.1:7447)",
    )
    ap.add_argument(
        "--listen",
        action="append",
        help="zenoh endpoint to listen on, repeatable (default tcp/127.0.0.1:0)",
    )
    ap.add_argument("--kp", type=float, default=100.0, help="K_P0, 1/s^2 (default 100)")
    ap.add_argument("--kd", type=float, default=14.14, help="K_D, 1/s (default 14.14)")
    ap.add_argument("--k", type=float, default=500.0, help="energy adaptation gain (default 500)")
    ap.add_argument(
        "--energy-avg",
        type=float,
        default=19.963439703027,
        help="E_av, J (default 19.963439703027, the stabilised orbit)",
    )
    ap.add_argument(
        "--zenoh-id",
        type=tilting_source.zenoh_id_arg,
        help="this session's zenoh id, 1 to 32 hex digits (default random); attached to every put",
    )
    ap.add_argument(
        "--plant-id",
        type=tilting_source.zenoh_id_arg,
        help="believe states only from this zenoh session (default: the session of the first "
        "state believed, until it is silent for 0.5 s)",
    )
    ap.add_argument("--self-test", action="store_true", help="check encodings and law, then exit")
    args = ap.parse_args(argv)
    if args.self_test:
        self_test()
        return
    args.connect = args.connect or ["tcp/127.0.0.1:7447"]
    args.listen = args.listen or ["tcp/127.0.0.1:0"]
    run(args)


if __name__ == "__main__":
    main()
