#!/usr/bin/env python3
"""A stand-alone tilting-system plant in pure Python, speaking the wire protocol of
docs/protocol.md over zenoh in lockstep: a drop-in replacement for `tilting-plant --clock lockstep`,
and the template to start from when putting a real robot on these topics.

It shares no code with the Rust workspace. The model (three contact modes, the zero-moment-point
switching, the landing impact) is written here from docs/model.md, the bytes from
docs/protocol.md. The integrator is a fixed-step classical Runge-Kutta (RK4, default step 0.1 ms)
with every switching time located by bisection on the step length.

The loop (lockstep): publish `PlantState` seq k on `tilting/{robot}/plant/state`, wait for the
`TorqueCommand` with seq k on `tilting/{robot}/controller/torque`, hold that torque over
[t_k, t_{k+1}] (zero-order hold) while integrating the hybrid dynamics, publish a `ModeEvent` on
`tilting/{robot}/plant/event` for each transition of the period, then state k + 1. A `Status`
goes to `tilting/{robot}/plant/status` at 10 Hz and on every change of its `state`; the
liveliness token `tilting/{robot}/alive/plant` is declared after the publishers and subscribers.

    python3 plant.py --duration 10 --record /tmp/run.csv      # then start any controller

To put a real robot here, replace `HybridPlant.advance` (integrate one period under a held
torque) by "apply the torque to the motor, wait for the next sample, read the encoders, and
report mode transitions": everything around it (the wire format, lockstep waiting, safe mode,
status, summary) stays as it is.

The model has the hardware terms of docs/model.md: the arm's centre of mass and inertia, a geared
rotor, viscous and Coulomb joint friction (`--params`), the latter with the Rust plant's stick/slip
treatment (the joint's phase, located like the mode transitions). `--measure angles` publishes
the angles only (`measured = 3`, protocol 2), with the Rust plant's encoder and noise flags
(`--encoder-counts`, `--noise-alpha` ..., `--seed`; Python's random stream, not the Rust one):
the controller then estimates the rates.

`--self-test` checks the encodings and the model without zenoh (energy conservation, mirror
symmetry, angular momentum across the impact, the zero moment point at rest);
examples/python/tests/test_plant.py (pytest) checks the friction and the sensors. At the end it
prints one JSON summary on stdout; the exit code is 0 (duration reached or Ctrl-C), 3 (a model
fault: fall, contact loss, Zeno, non-finite torque) or 1 (bad arguments).
"""

import argparse
import collections
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

# Protocol 2: seq, time, alpha, beta, alpha_dot, beta_dot, mode, measured (which fields carry a
# measurement: bit 0 alpha, bit 1 beta, bit 2 alpha_dot, bit 3 beta_dot; 15 all four, 3 the
# angles only, `--measure angles`: an absent rate's slot holds +0.0 and must not be read).
PLANT_STATE = struct.Struct("<Q5d2B")
MEASURED_FULL, MEASURED_ANGLES = 15, 3
TORQUE = struct.Struct("<Qd")  # seq, tau
MODE_EVENT = struct.Struct("<Qd2B8d")  # seq, time, from, to, x_before[4], x_after[4]
STATUS_HEAD = struct.Struct("<QdBB7Q5d3Q3dQ")  # ... then `fault` length n, n bytes of UTF-8
assert (PLANT_STATE.size, TORQUE.size, MODE_EVENT.size, STATUS_HEAD.size) == (50, 16, 82, 170)

FLAT, LEFT, RIGHT = 0, 1, 2
MODE_NAMES = {FLAT: "flat", LEFT: "left", RIGHT: "right"}
# Status.state
STARTING, RUNNING, SAFE, FAULTED, STOPPED = 0, 1, 2, 3, 4
MAX_FAULT_BYTES = 1024


def pack_state(seq, t, mode, x, measured=MEASURED_FULL):
    """A PlantState; with measured = MEASURED_ANGLES the rates of x are left out (+0.0)."""
    if measured == MEASURED_ANGLES:
        return PLANT_STATE.pack(seq, t, x[0], x[1], 0.0, 0.0, mode, measured)
    return PLANT_STATE.pack(seq, t, x[0], x[1], x[2], x[3], mode, measured)


def pack_event(seq, ev):
    return MODE_EVENT.pack(seq, ev.t, ev.frm, ev.to, *ev.x_before, *ev.x_after)


def pack_status(fields, fault):
    """fields: the 22 values of the fixed part before the fault length, in table order."""
    text = fault.encode("utf-8")
    if len(text) > MAX_FAULT_BYTES:  # cut on a character boundary
        text = text[:MAX_FAULT_BYTES].decode("utf-8", "ignore").encode("utf-8")
    return STATUS_HEAD.pack(*fields, len(text)) + text


def unpack_torque(payload):
    """Decodes and validates a TorqueCommand; raises ValueError naming the problem."""
    if len(payload) != TORQUE.size:
        raise ValueError(
            f"TorqueCommand: wrong payload size: expected {TORQUE.size} bytes, got {len(payload)}"
        )
    seq, tau = TORQUE.unpack(payload)
    if not math.isfinite(tau):
        raise ValueError(f"TorqueCommand.tau = {tau} is not finite")
    return seq, tau


# ---------------------------------------------------------------------------------------------
# Model (docs/model.md). A foot plate of length 2f with a point mass m_f at its centre; an arm of
# length l with a point mass m_l at its tip, on a joint at the plate centre. World origin at the
# left plate edge, x right, y up. State x = (alpha, beta, alpha_dot, beta_dot): plate tilt
# (> 0 only over the left edge, < 0 only over the right edge) and arm angle relative to the
# plate (pi/2 upright). Modes: flat, tilted left (pivot (0, 0)), tilted right (pivot (2f, 0)):
# the right-tilt equations are the left ones with f replaced by -f.


class Params:
    """The paper's point masses, plus the hardware terms of docs/model.md ("A plant that looks
    like hardware"): the arm's centre of mass at l_c (m; None: the tip) with its inertia i_l
    (kg m^2), a rotor j_m (kg m^2) behind the gear ratio n_g, viscous friction b_v (N m s/rad)
    and Coulomb friction tau_c (N m) at the joint, the latter with stick/slip phases (`Joint`)."""

    KEYS = ("m_f", "m_l", "l", "f", "g", "l_c", "i_l", "j_m", "n_g", "b_v", "tau_c")

    def __init__(
        self,
        m_f=1.0,
        m_l=1.0,
        l=2.0,
        f=0.5,
        g=9.81,
        l_c=None,
        i_l=0.0,
        j_m=0.0,
        n_g=1.0,
        b_v=0.0,
        tau_c=0.0,
    ):
        self.m_f, self.m_l, self.l, self.f, self.g = m_f, m_l, l, f, g
        self.lc = l if l_c is None else l_c
        self.i_l, self.j_m, self.n_g, self.b_v, self.tau_c = i_l, j_m, n_g, b_v, tau_c
        self.has_inertia = i_l != 0.0 or j_m != 0.0
        # The spins' share of the mass matrix (kg m^2): the arm turns with alpha + beta, the
        # rotor with alpha + n_g beta.
        self.i11, self.i12, self.i22 = i_l + j_m, i_l + n_g * j_m, i_l + n_g * n_g * j_m

    def signed_f(self, mode):
        """+f seen from the left pivot (and flat), -f from the right pivot."""
        return -self.f if mode == RIGHT else self.f

    @staticmethod
    def from_toml(path):
        import tomllib  # Python >= 3.11

        with open(path, "rb") as fh:
            d = tomllib.load(fh)
        unknown = set(d) - set(Params.KEYS)
        if unknown:
            raise SystemExit(f"--params {path}: unknown keys {sorted(unknown)}")
        p = Params(**{k: float(v) for k, v in d.items()})
        for k in ("m_f", "m_l", "l", "f", "g", "n_g"):
            v = getattr(p, k)
            if not (math.isfinite(v) and v > 0.0):
                raise SystemExit(f"--params {path}: {k} = {v}; allowed: finite and > 0")
        for k in ("i_l", "j_m", "b_v", "tau_c"):
            v = getattr(p, k)
            if not (math.isfinite(v) and v >= 0.0):
                raise SystemExit(f"--params {path}: {k} = {v}; allowed: finite and >= 0")
        if not (math.isfinite(p.lc) and 0.0 < p.lc <= p.l):
            raise SystemExit(f"--params {path}: l_c = {p.lc}; allowed: finite, > 0 and <= l")
        return p


def mass_matrix(p, mode, beta):
    """(M11, M12, M22) of the tilted double pendulum about the pivot."""
    sf, lc = p.signed_f(mode), p.lc
    cb = math.cos(beta)
    m11 = p.m_f * sf * sf + p.m_l * (sf * sf + 2.0 * sf * lc * cb + lc * lc)
    m12 = p.m_l * lc * (lc + sf * cb)
    m22 = p.m_l * lc * lc
    if p.has_inertia:  # skipped, not added as zeros: the paper's numbers stay the same bits
        return m11 + p.i11, m12 + p.i12, m22 + p.i22
    return m11, m12, m22


def bias(p, mode, x):
    """(h1, h2): Coriolis, centrifugal and gravity terms of the tilted equations."""
    alpha, beta, ad, bd = x
    sf = p.signed_f(mode)
    sb = math.sin(beta)
    cab = math.cos(alpha + beta)
    h1 = (
        -p.m_l * sf * p.lc * sb * (2.0 * ad * bd + bd * bd)
        + (p.m_f + p.m_l) * p.g * sf * math.cos(alpha)
        + p.m_l * p.g * p.lc * cab
    )
    h2 = p.m_l * p.lc * (sf * sb * ad * ad + p.g * cab)
    return h1, h2


# The joint's Coulomb-friction phase (docs/model.md, "Coulomb friction and sticking"): free (no
# Coulomb friction), sliding forward (beta_dot > 0, friction -tau_c on the arm), sliding backward
# (beta_dot < 0, friction +tau_c), or stuck (beta_dot = 0: the arm and the plate move as one
# body, the friction supplying whatever torque in [-tau_c, tau_c] that takes). The phase is part
# of the discrete state beside the mode; it is not on the wire.
FREE, FORWARD, BACKWARD, STUCK = 0, 1, 2, 3
JOINT_NAMES = {FREE: "free", FORWARD: "forward", BACKWARD: "backward", STUCK: "stuck"}


def rigid_torque(p, mode, x, v):
    """The net joint torque (N m) that gives beta_ddot = v (rad/s^2): the rigid-body inverse
    dynamics, no friction. Tilted, alpha_ddot is eliminated with the plate's (unactuated) row."""
    if mode == FLAT:
        if p.has_inertia:
            return mass_matrix(p, FLAT, x[1])[2] * v + p.m_l * p.lc * p.g * math.cos(x[1])
        return p.m_l * p.lc * (p.lc * v + p.g * math.cos(x[1]))
    m11, m12, m22 = mass_matrix(p, mode, x[1])
    h1, h2 = bias(p, mode, x)
    alpha_ddot = -(m12 * v + h1) / m11
    return m12 * alpha_ddot + m22 * v + h2


def hold_torque(p, mode, x):
    """The net joint torque (N m) that holds the arm still relative to the plate (beta_ddot = 0):
    what a stuck joint transmits. Flat m_l g l_c cos(beta), tilted h2 - M12 h1 / M11."""
    return rigid_torque(p, mode, x, 0.0)


def joint_of(p, mode, x, tau):
    """The joint's phase at state x under the motor torque tau (N m), Karnopp's rule: sliding the
    way beta_dot points; at beta_dot = 0 stuck while |tau - tau_h| < tau_c (tau_h the hold
    torque), else sliding the way tau - tau_h pushes."""
    if p.tau_c == 0.0:
        return FREE
    if x[3] > 0.0:
        return FORWARD
    if x[3] < 0.0:
        return BACKWARD
    excess = tau - hold_torque(p, mode, x)
    if abs(excess) < p.tau_c:
        return STUCK
    return FORWARD if excess > 0.0 else BACKWARD


def net_torque(p, bd, tau, joint=FREE):
    """The net joint torque on the sliding (or free) arm (N m): the motor's tau less the viscous
    friction b_v beta_dot and less the Coulomb friction tau_c the way it slides."""
    if p.b_v != 0.0:
        tau = tau - p.b_v * bd
    if joint == FORWARD:
        return tau - p.tau_c
    if joint == BACKWARD:
        return tau + p.tau_c
    return tau


def accelerations(p, mode, x, motor_tau, joint=None):
    """Forward dynamics: (alpha_ddot, beta_ddot) (rad/s^2) under the motor torque (N m), friction
    included, in the joint phase `joint` (None: the phase Karnopp's rule gives at x). Stuck, the
    arm and the plate move as one body: flat nothing moves, tilted M11 alpha_ddot = -h1."""
    if joint is None:
        joint = joint_of(p, mode, x, motor_tau)
    beta = x[1]
    if joint == STUCK:
        if mode == FLAT:
            return 0.0, 0.0
        return -bias(p, mode, x)[0] / mass_matrix(p, mode, beta)[0], 0.0
    tau = net_torque(p, x[3], motor_tau, joint)
    if mode == FLAT:
        # tau = M22 beta_ddot + m_l g l_c cos beta, the plate does not move.
        if p.has_inertia:
            return 0.0, (tau - p.m_l * p.lc * p.g * math.cos(beta)) / mass_matrix(p, FLAT, beta)[2]
        return 0.0, (tau / (p.m_l * p.lc) - p.g * math.cos(beta)) / p.lc
    m11, m12, m22 = mass_matrix(p, mode, beta)
    h1, h2 = bias(p, mode, x)
    # M [alpha_ddot, beta_ddot]^T = [-h1, tau - h2]^T (the plate row has no torque).
    det = m11 * m22 - m12 * m12
    return (m22 * -h1 - m12 * (tau - h2)) / det, (m11 * (tau - h2) + m12 * h1) / det


def rhs(p, mode, x, tau, joint=None):
    """dx/dt in the joint phase `joint` (None: Karnopp's rule at x)."""
    add, bdd = accelerations(p, mode, x, tau, joint)
    return (x[2], x[3], add, bdd)


def vertical_force(p, mode, x, add, bdd):
    """Vertical ground force on the plate (N): Newton's law for the two point masses,
    F_y = m_f (g + y_f'') + m_l (g + y_l''). Heights above the pivot: y_f = sf sin(alpha),
    y_l = y_f + l sin(alpha + beta). Flat (alpha = 0) this is the F_y of docs/model.md."""
    alpha, beta, ad, bd = x
    sf = p.signed_f(mode)
    yf_dd = sf * (math.cos(alpha) * add - math.sin(alpha) * ad * ad)
    w = ad + bd
    yl_dd = yf_dd + p.lc * (math.cos(alpha + beta) * (add + bdd) - math.sin(alpha + beta) * w * w)
    return p.m_f * (p.g + yf_dd) + p.m_l * (p.g + yl_dd)


def energy(p, mode, x):
    """E = T + V from the positions and velocities of the two point masses (ground at y = 0)."""
    alpha, beta, ad, bd = x
    sf = p.signed_f(mode)
    sa, ca = math.sin(alpha), math.cos(alpha)
    sab, cab = math.sin(alpha + beta), math.cos(alpha + beta)
    y_f = sf * sa
    y_l = y_f + p.lc * sab
    vf = (-sf * ad * sa, sf * ad * ca)
    vl = (vf[0] - p.lc * (ad + bd) * sab, vf[1] + p.lc * (ad + bd) * cab)
    kinetic = 0.5 * (p.m_f * (vf[0] ** 2 + vf[1] ** 2) + p.m_l * (vl[0] ** 2 + vl[1] ** 2))
    if p.has_inertia:  # the arm's and the rotor's spins
        kinetic += 0.5 * (p.i_l * (ad + bd) ** 2 + p.j_m * (ad + p.n_g * bd) ** 2)
    return kinetic + p.g * (p.m_f * y_f + p.m_l * y_l)


def impact_gain(p, law, mode, beta):
    """c(beta) of the landing map beta_dot+ = beta_dot- + c alpha_dot-, for a tilt in `mode`."""
    sf = p.signed_f(mode)
    if law == "paper":
        # Angular momentum about the pivot edge kept: the momentum conjugate to alpha,
        # M11 alpha_dot + M12 beta_dot, before equals M12 beta_dot+ after (alpha_dot+ = 0).
        m11, m12, _ = mass_matrix(p, mode, beta)
        return m11 / m12
    # "striking-edge": the rocking-block law, angular momentum about the edge that hits.
    num, den = p.m_l * p.lc**2, p.m_l * p.lc * (p.lc - sf * math.cos(beta))
    if p.has_inertia:  # the spins' momentum about the striking edge
        num, den = num + p.i11, den + p.i12
    return (num - (p.m_f + p.m_l) * sf * sf) / den


def torque_for_beta_ddot(p, mode, x, v):
    """Computed torque: the motor torque (N m) that makes beta_ddot = v in `mode` (safe mode),
    friction compensated: + b_v beta_dot, and + tau_c sign(beta_dot) while sliding, + tau_c
    sign(v) from rest (the excess over the hold torque is then outside the band), nothing at rest
    with v = 0 (it sticks)."""
    tau = rigid_torque(p, mode, x, v)
    if p.b_v != 0.0:
        tau += p.b_v * x[3]
    if p.tau_c != 0.0:
        s = x[3] if x[3] != 0.0 else v
        if s > 0.0:
            return tau + p.tau_c
        if s < 0.0:
            return tau - p.tau_c
    return tau


def plate_torque(p, beta, bdd):
    """The torque the arm and the rotor put on the flat plate (N m), from the arm's
    acceleration: m_l l_c (l_c beta_ddot + g cos beta) + (i_l + n_g j_m) beta_ddot."""
    t = p.m_l * p.lc * (p.lc * bdd + p.g * math.cos(beta))
    return t + p.i12 * bdd if p.has_inertia else t


# ---------------------------------------------------------------------------------------------
# The hybrid simulator: what a real robot replaces.


class Fault(Exception):
    """The model stops here: contact loss, fall, Zeno, non-finite torque."""


class Transition:
    __slots__ = ("t", "frm", "to", "x_before", "x_after")

    def __init__(self, t, frm, to, x_before, x_after):
        self.t, self.frm, self.to = t, frm, to
        self.x_before, self.x_after = tuple(x_before), tuple(x_after)


def rk4(p, mode, tau, x, dt, k1, joint=FREE):
    """One classical Runge-Kutta step of length dt from x, with k1 = rhs(x) given, in the joint
    phase `joint` (fixed over the step: its vector field is smooth). As a function of dt it is a
    polynomial: a continuous fourth-order solution on the whole step, which is what the event
    location bisects on."""
    h2 = 0.5 * dt
    k2 = rhs(p, mode, [x[i] + h2 * k1[i] for i in range(4)], tau, joint)
    k3 = rhs(p, mode, [x[i] + h2 * k2[i] for i in range(4)], tau, joint)
    k4 = rhs(p, mode, [x[i] + dt * k3[i] for i in range(4)], tau, joint)
    return tuple(x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(4))


# Event slots. Each event function is positive inside its mode and fires when it reaches zero
# from above (docs/model.md, trap 1): a tilt starts at alpha = alpha_dot = 0, so its landing
# function starts at exactly 0 and cannot fire before alpha has left 0.
EV_A, EV_B, EV_CONTACT, EV_FALL, EV_JOINT = 0, 1, 2, 3, 4
NEV = 5
# Flat:   A = left support margin f F_y + tau,  B = right margin f F_y - tau.
# Tilted: A = landing (s alpha),  B = extreme of alpha (s alpha_dot; not terminal: a tilt peak).
# Every mode: JOINT = the end of the joint's phase: sliding s beta_dot (s = +1 forward, -1
# backward), stuck tau_c - |tau - tau_h|, free the constant 1.


def fires(i, g0, g1):
    """Did event i fire over a step? It reached 0 from above; the joint's event also fires on a
    slide that starts at rest (g0 = 0) and at once turns the other way (g1 < 0): the slide ends
    there instead of the friction pushing the arm (docs/model.md)."""
    return (g0 > 0.0 and g1 <= 0.0) or (i == EV_JOINT and g0 == 0.0 and g1 < 0.0)


class HybridPlant:
    """The hybrid state (t, mode, x) and one method, `advance(tau, t_target)`, which integrates
    with tau held. Fixed RK4 steps of at most `h_max`; a switching time is located to `event_tol`
    seconds by bisection on the step length (trap 4 of docs/model.md)."""

    def __init__(
        self,
        mode,
        x0,
        params=None,
        impact="paper",
        h_max=1e-4,
        event_tol=1e-13,
        fall_angle=math.pi / 2,
        zeno_events=16,
        zeno_window=1e-3,
    ):
        self.p = params or Params()
        self.impact = impact
        self.h_max, self.event_tol, self.fall_angle = h_max, event_tol, fall_angle
        self.t, self.mode, self.x = 0.0, mode, tuple(float(v) for v in x0)
        # The joint's phase from the sign of beta_dot (at rest: stuck until the first torque
        # decides, at the start of the first advance).
        if self.p.tau_c == 0.0:
            self.joint = FREE
        else:
            self.joint = FORWARD if self.x[3] > 0.0 else BACKWARD if self.x[3] < 0.0 else STUCK
        self.joint_events = 0  # stick/slip changes so far
        self.joint_changes = []  # (t, from, to, x) of the current advance() call
        if mode == FLAT and (self.x[0] != 0.0 or self.x[2] != 0.0):
            raise ValueError("mode flat needs alpha = alpha_dot = 0")
        if (mode == LEFT and self.x[0] < 0.0) or (mode == RIGHT and self.x[0] > 0.0):
            raise ValueError("alpha must lie on the side of the tilt (or be 0)")
        self.recent = collections.deque(maxlen=zeno_events)  # Zeno guard (trap 5)
        self.zeno_window = zeno_window
        self.transitions = []  # of the current advance() call
        self.extreme = None  # (t, alpha) of the largest |alpha| extreme of the tilt in progress
        self.peaks = collections.deque(maxlen=256)  # (t, alpha) of the tilt peaks
        self.tilts = 0  # flat -> tilted transitions

    # -- event functions --------------------------------------------------------------------

    def sign(self):
        return 1.0 if self.mode == LEFT else -1.0

    def joint_event(self, x, tau):
        """The joint's event function at x under the held motor torque tau."""
        if self.joint == FREE:
            return 1.0
        if self.joint == FORWARD:
            return x[3]
        if self.joint == BACKWARD:
            return -x[3]
        return self.p.tau_c - abs(tau - hold_torque(self.p, self.mode, x))

    def events(self, x, xd, tau):
        """The five event functions at x with derivative xd = rhs(x) in the current mode and
        joint phase."""
        p = self.p
        fy = vertical_force(p, self.mode, x, xd[2], xd[3])
        gj = self.joint_event(x, tau)
        if self.mode == FLAT:
            if p.has_inertia or p.b_v != 0.0 or p.tau_c != 0.0:
                tau = plate_torque(p, x[1], xd[3])  # what the plate feels (docs/model.md)
            return (p.f * fy + tau, p.f * fy - tau, fy, 1.0, gj)
        s = self.sign()
        return (s * x[0], s * x[2], fy, self.fall_angle - s * x[0], gj)

    # -- discrete transitions ---------------------------------------------------------------

    def record(self, to, x_after):
        self.transitions.append(Transition(self.t, self.mode, to, self.x, x_after))
        if self.mode == FLAT and to != FLAT:
            self.tilts += 1
        self.mode, self.x = to, tuple(x_after)
        self.count_for_zeno()

    def count_for_zeno(self):
        """Counts a transition or a joint event at the current time for the Zeno guard."""
        if len(self.recent) == self.recent.maxlen and self.t - self.recent[0] < self.zeno_window:
            raise Fault(
                f"Zeno guard at t = {self.t:.9f} s: {self.recent.maxlen} transitions within "
                f"{self.zeno_window:g} s"
            )
        self.recent.append(self.t)

    def settle_joint(self, tau):
        """With Coulomb friction: the joint's phase at the current state under the held torque
        (Karnopp's rule), recorded when it changes. Called wherever the torque or the state
        jumps: at each advance's start, after every transition and joint event."""
        if self.p.tau_c == 0.0:
            return
        to = joint_of(self.p, self.mode, self.x, tau)
        if to != self.joint:
            self.joint_changes.append((self.t, self.joint, to, self.x))
            self.joint, self.joint_events = to, self.joint_events + 1
            self.count_for_zeno()

    def start_tilt(self, to, tau):
        """Flat -> tilted: the state is continuous, alpha = alpha_dot = 0. A tilt whose
        acceleration points into the ground is not one: it lands at once (trap 2)."""
        self.extreme = None
        self.record(to, (0.0, self.x[1], 0.0, self.x[3]))
        self.settle_joint(tau)
        add, _ = accelerations(self.p, self.mode, self.x, tau, self.joint)
        if self.sign() * add < -1e-9:  # below this it is round-off at a located switch
            self.land()

    def land(self):
        """Tilted -> flat with the impact map: alpha+ = alpha_dot+ = 0, beta+ = beta-,
        beta_dot+ = beta_dot- + c(beta) alpha_dot-."""
        if self.extreme is not None:
            self.peaks.append(self.extreme)
            self.extreme = None
        _, beta, ad, bd = self.x
        c = impact_gain(self.p, self.impact, self.mode, beta)
        self.x = (0.0, beta, ad, bd)  # located to round-off: the impact happens on the ground
        self.record(FLAT, (0.0, beta, 0.0, bd + c * ad))

    def settle(self, tau):
        """Flat: check the support margins directly, not only by watching for a crossing: the
        held torque jumps at every sample and the zero moment point with it (trap 3). Tilts at
        once if the zero moment point lies outside the support; a contact loss is a fault."""
        self.settle_joint(tau)
        while self.mode == FLAT:
            xd = rhs(self.p, FLAT, self.x, tau, self.joint)
            g = self.events(self.x, xd, tau)
            if g[EV_CONTACT] <= 0.0:
                raise Fault(
                    f"contact loss at t = {self.t:.9f} s in mode flat: vertical contact force "
                    f"F_y = {g[EV_CONTACT]:.3e} N <= 0"
                )
            if g[EV_A] < 0.0:
                self.start_tilt(LEFT, tau)
            elif g[EV_B] < 0.0:
                self.start_tilt(RIGHT, tau)
            else:
                break
            self.settle_joint(tau)

    def check_tilt_direction(self, tau):
        """A tilted state at alpha = 0 moving (or accelerating) into the ground lands at once."""
        if self.mode == FLAT:
            return
        s = self.sign()
        if s * self.x[0] > 0.0:
            return
        if self.x[2] != 0.0:
            into_ground = s * self.x[2] < 0.0
        else:
            into_ground = s * accelerations(self.p, self.mode, self.x, tau, self.joint)[0] < 0.0
        if into_ground:
            self.land()
            self.settle(tau)

    # -- continuous flow ----------------------------------------------------------------------

    def locate(self, i, x0, k1, dt, tau):
        """The zero of event i within the step (0, dt], to event_tol, by bisection; returns the
        right end of the last bracket (already past the event, like docs/model.md asks)."""
        lo, hi = 0.0, dt
        while hi - lo > self.event_tol:
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            xm = rk4(self.p, self.mode, tau, x0, mid, k1, self.joint)
            gm = self.events(xm, rhs(self.p, self.mode, xm, tau, self.joint), tau)[i]
            if gm > 0.0:
                lo = mid
            else:
                hi = mid
        return hi

    def advance(self, tau, t_target):
        """Integrates from self.t to t_target with tau held; returns the transitions."""
        self.transitions, self.joint_changes = [], []
        if not math.isfinite(tau):
            raise Fault(f"non-finite torque {tau} at t = {self.t:.9f} s")
        self.settle(tau)
        self.check_tilt_direction(tau)
        p = self.p
        while self.t < t_target:
            mode, joint = self.mode, self.joint
            x0 = self.x
            k1 = rhs(p, mode, x0, tau, joint)
            g0 = self.events(x0, k1, tau)
            rest = t_target - self.t
            n = max(1, math.ceil(rest / self.h_max * (1.0 - 1e-12)))
            dt = rest / n
            x1 = rk4(p, mode, tau, x0, dt, k1, joint)
            g1 = self.events(x1, rhs(p, mode, x1, tau, joint), tau)
            fired = [i for i in range(NEV) if fires(i, g0[i], g1[i])]
            if not fired:
                self.t = t_target if n == 1 else self.t + dt
                self.x = x1
                continue
            roots = sorted((self.locate(i, x0, k1, dt, tau), i) for i in fired)
            terminal = next(((r, i) for r, i in roots if mode == FLAT or i != EV_B), None)
            for r, i in roots:
                if mode != FLAT and i == EV_B and (terminal is None or r <= terminal[0]):
                    a = rk4(p, mode, tau, x0, r, k1, joint)[0]
                    if self.extreme is None or abs(a) > abs(self.extreme[1]):
                        self.extreme = (self.t + r, a)
            if terminal is None:
                self.t = t_target if n == 1 else self.t + dt
                self.x = x1
                continue
            r, i = terminal
            self.t = min(self.t + r, t_target)
            self.x = rk4(p, mode, tau, x0, r, k1, joint)
            if i == EV_JOINT:
                if joint != STUCK:
                    # A sliding arm came to rest: located to round-off, like a landing.
                    self.x = (self.x[0], self.x[1], self.x[2], 0.0)
                self.settle(tau)  # Karnopp's rule decides the next phase, then the margins
                self.check_tilt_direction(tau)
                continue
            if i == EV_CONTACT:
                raise Fault(
                    f"contact loss at t = {self.t:.9f} s in mode {MODE_NAMES[mode]}: vertical "
                    f"contact force reached 0"
                )
            if i == EV_FALL:
                raise Fault(f"fall at t = {self.t:.9f} s: |alpha| reached {abs(self.x[0]):.4f} rad")
            if mode == FLAT:
                self.start_tilt(LEFT if i == EV_A else RIGHT, tau)
            else:
                self.land()
            self.settle(tau)
        return self.transitions

    def peak_in_progress(self):
        """The peak of a tilt that has not landed yet, if alpha has already turned back."""
        return self.extreme if self.mode != FLAT else None


# ---------------------------------------------------------------------------------------------
# The sensors (the flags of `tilting-plant`: --measure, --noise-*, --encoder-counts, --seed).

NOISE_FLAGS = ("--noise-alpha", "--noise-beta", "--noise-alpha-dot", "--noise-beta-dot")
MAX_SIGMA = 10.0  # rad or rad/s
COUNTS_RANGE = (2, 1 << 32)


class Sensor:
    """What the controller sees of the true state, as the Rust plant's `imperfect::Sensor`
    defines it: the angles y = round((x + sigma n) / q) q with n standard normal and q = 2 pi /
    counts the encoder's resolution (no rounding without an encoder), the rates y = x + sigma n
    (a separate rate sensor, not derived from the quantised angles). Four normals are drawn per
    sample, in state order, whenever any deviation is positive. With `angles_only` the rates are
    not sent (`measured = 3`). The stream is Python's `random.Random(seed)`, not the Rust plant's
    ChaCha8: the same statistics, not the same numbers."""

    def __init__(self, noise=(0.0, 0.0, 0.0, 0.0), encoder_counts=None, seed=0, angles_only=False):
        import random

        self.sigma = tuple(float(v) for v in noise)
        self.quantum = None if encoder_counts is None else 2.0 * math.pi / encoder_counts
        self.angles_only = angles_only
        self.measured = MEASURED_ANGLES if angles_only else MEASURED_FULL
        self.rng = random.Random(seed)

    def measure(self, x):
        """All four measured quantities of the true state x (draws one sample of the noise)."""
        y = list(x)
        if any(s > 0.0 for s in self.sigma):
            for i, s in enumerate(self.sigma):
                n = self.rng.gauss(0.0, 1.0)
                if s > 0.0:
                    y[i] += s * n
        if self.quantum is not None:
            for i in (0, 1):
                y[i] = round_half_away(y[i] / self.quantum) * self.quantum
        return tuple(y)


def round_half_away(v):
    """The nearest integer, halves away from zero (Rust's f64::round; Python's round() takes
    halves to even)."""
    a = abs(v)
    r = math.floor(a)
    if a - r >= 0.5:
        r += 1.0
    return math.copysign(r, v)


def state_for_safe_mode(y, angles_only, t, previous):
    """The safe mode's state from the measurement y: the measured rates, or with the angles only
    the backward difference of the measured angles over the last sample interval (zero at the
    first sample), as the Rust plant does; `previous` is (t, alpha, beta) of the sample before."""
    if not angles_only:
        return y
    if previous is not None and t > previous[0]:
        dt = t - previous[0]
        return (y[0], y[1], (y[0] - previous[1]) / dt, (y[1] - previous[2]) / dt)
    return (y[0], y[1], 0.0, 0.0)


# ---------------------------------------------------------------------------------------------
# Self-test: no zenoh needed. The checks of "Checking an implementation" in docs/model.md.


def self_test():
    # Encodings: the worked examples of docs/protocol.md.
    state = pack_state(42, 1.5, LEFT, (0.25, math.pi / 2, -0.5, 2.0))
    assert state.hex() == (
        "2a00000000000000000000000000f83f000000000000d03f182d4454fb21f93f"
        "000000000000e0bf0000000000000040010f"
    ), state.hex()
    assert unpack_torque(bytes.fromhex("2a00000000000000000000000000c0bf")) == (42, -0.125)
    for bad in (b"\x00" * 15, TORQUE.pack(1, math.inf)):
        try:
            unpack_torque(bad)
        except ValueError:
            pass
        else:
            raise AssertionError(f"accepted {bad.hex()}")
    st = pack_status(
        (1, 0.5, RUNNING, LEFT, 2, 3, 4, 0, 0, 0, 0, 0.0, 0.0, 0.0, 1.0, 2.0, 0, 0, 0, 0.0, 0.0, 0.0),
        "",
    )
    assert len(st) == 170
    assert len(pack_status((0,) * 11 + (0.0,) * 5 + (0,) * 3 + (0.0,) * 3, "é" * 600)) <= 170 + 1024

    p = Params()
    # Energy against the mass-matrix form T = 1/2 qd^T M qd.
    for mode, x in ((LEFT, (0.1, 1.7, -0.3, 0.2)), (RIGHT, (-0.2, 1.4, 0.5, -0.6))):
        m11, m12, m22 = mass_matrix(p, mode, x[1])
        sf = p.signed_f(mode)
        e = 0.5 * (m11 * x[2] ** 2 + 2 * m12 * x[2] * x[3] + m22 * x[3] ** 2) + p.g * (
            (p.m_f + p.m_l) * sf * math.sin(x[0]) + p.m_l * p.lc * math.sin(x[0] + x[1])
        )
        assert abs(e - energy(p, mode, x)) < 1e-12 * abs(e), (mode, e)

    # The hardware terms (docs/model.md): the same identity with the arm's centre of mass off
    # the tip, its inertia and a geared rotor; passive motion with them conserves energy; viscous
    # friction dissipates b_v beta_dot^2 (trapezoid rule on the 1e-4 s steps: O(dt^2), 1e-7 J).
    hw = Params(l_c=1.4, i_l=0.25, j_m=0.002, n_g=9.0)
    for mode, x in ((LEFT, (0.1, 1.7, -0.3, 0.2)), (RIGHT, (-0.2, 1.4, 0.5, -0.6))):
        m11, m12, m22 = mass_matrix(hw, mode, x[1])
        sf = hw.signed_f(mode)
        e = 0.5 * (m11 * x[2] ** 2 + 2 * m12 * x[2] * x[3] + m22 * x[3] ** 2) + hw.g * (
            (hw.m_f + hw.m_l) * sf * math.sin(x[0]) + hw.m_l * hw.lc * math.sin(x[0] + x[1])
        )
        assert abs(e - energy(hw, mode, x)) < 1e-12 * abs(e), (mode, e)
    for q, tol in ((hw, 1e-9), (Params(l_c=1.4, i_l=0.25, j_m=0.002, n_g=9.0, b_v=0.3), 1e-7)):
        for mode, x in ((LEFT, (0.3, 1.0, 0.0, 4.0)), (FLAT, (0.0, 0.3, 0.0, 4.0))):
            e0, lost, dt = energy(q, mode, x), 0.0, 1e-4
            for _ in range(10000):
                x1 = rk4(q, mode, 0.0, x, dt, rhs(q, mode, x, 0.0))
                lost += 0.5 * dt * q.b_v * (x[3] ** 2 + x1[3] ** 2)
                x = x1
            err = abs(e0 - energy(q, mode, x) - lost)
            assert err < tol * max(1.0, abs(e0)) and (q.b_v == 0.0 or lost > 0.5), (mode, err, lost)

    # Passive tilting (tau = 0) conserves energy: the integrator on the tilted equations, a
    # whirling double pendulum for 2 s at the default step (no switching: a passive plate falls).
    x, dt = (0.3, 1.0, 0.0, 4.0), 1e-4
    e0 = energy(p, LEFT, x)
    for _ in range(20000):
        x = rk4(p, LEFT, 0.0, x, dt, rhs(p, LEFT, x, 0.0))
    drift = abs(energy(p, LEFT, x) - e0) / abs(e0)
    assert drift < 1e-9, f"passive energy drift {drift:e}"

    # Mirror symmetry: (alpha, beta) -> (-alpha, pi - beta), rates negated, torque negated,
    # maps a left tilt onto a right one, including its landing and the impact.
    def run(mode, x0, tau):
        s = HybridPlant(mode, x0)
        evs = []
        for k in range(1, 501):
            evs += s.advance(tau(s.mode, s.x), k * 1e-3)
        return s, evs

    def law(mode, x):  # the paper's PD (K_P = 100, K_D = 14.14), computed torque
        return torque_for_beta_ddot(p, mode, x, 100.0 * (math.pi / 2 - x[1]) - 14.14 * x[3])

    def mirror(x):
        return (-x[0], math.pi - x[1], -x[2], -x[3])

    x0 = (0.0, math.pi / 2 - 0.000214877415, 0.0, 0.498257789692)
    a, ea = run(LEFT, x0, law)
    b, eb = run(RIGHT, mirror(x0), law)
    assert [e.to for e in ea] and [e.to for e in ea] == [
        {LEFT: RIGHT, RIGHT: LEFT, FLAT: FLAT}[e.to] for e in eb
    ], ([(e.t, e.to) for e in ea], [(e.t, e.to) for e in eb])
    for u, v in zip(ea, eb):
        assert abs(u.t - v.t) < 1e-9, (u.t, v.t)
    assert max(abs(u - v) for u, v in zip(mirror(a.x), b.x)) < 1e-9, (a.x, b.x)

    # Angular momentum about the pivot edge is the same just before and just after a landing
    # (paper law): before M11 alpha_dot + M12 beta_dot, after (flat) M12 beta_dot.
    land = next(e for e in ea if e.to == FLAT)
    m11, m12, _ = mass_matrix(p, land.frm, land.x_before[1])
    before = m11 * land.x_before[2] + m12 * land.x_before[3]
    after = m12 * land.x_after[3]
    assert abs(before - after) < 1e-12 * abs(before), (before, after)
    assert land.x_after[0] == 0.0 and land.x_after[2] == 0.0

    # At rest the zero moment point r_z = f + tau / F_y is the horizontal position of the
    # centre of mass.
    beta = 1.2
    tau = torque_for_beta_ddot(p, FLAT, (0.0, beta, 0.0, 0.0), 0.0)
    fy = vertical_force(p, FLAT, (0.0, beta, 0.0, 0.0), 0.0, 0.0)
    com = (p.m_f * p.f + p.m_l * (p.f + p.l * math.cos(beta))) / (p.m_f + p.m_l)
    assert abs(p.f + tau / fy - com) < 1e-14, (p.f + tau / fy, com)

    # A torque that puts the zero moment point outside the support tilts the plate at once
    # (trap 3), over the edge it leaves by.
    s = HybridPlant(FLAT, (0.0, math.pi / 2, 0.0, 0.0))
    evs = s.advance(-40.0, 1e-3)
    assert evs and evs[0].t == 0.0 and evs[0].to == LEFT, [(e.t, e.to) for e in evs]
    print("self-test passed")


# ---------------------------------------------------------------------------------------------
# The zenoh node.

ROBOT_RE = re.compile(r"^[A-Za-z0-9_-]+$")


def session_config(zenoh, listen, connect):
    """The session of docs/protocol.md: peer mode, multicast scouting off, gossip on, explicit
    endpoints (the plant listens on tcp/127.0.0.1:7447 and connects nowhere by default)."""
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
            print(f"plant.py: dropped {self.what}: {msg}{extra}", file=sys.stderr, flush=True)
            self.last, self.suppressed = now, 0
        else:
            self.suppressed += 1


def percentile(sorted_values, q):
    if not sorted_values:
        return 0.0
    return sorted_values[min(len(sorted_values) - 1, int(q * len(sorted_values)))]


class Node:
    """Lockstep plant node: the state, the torque inbox and the counters, shared between the
    main loop and zenoh's callback threads under one lock."""

    def __init__(self, args, zenoh):
        self.args, self.zenoh = args, zenoh
        self.prefix = f"tilting/{args.robot}"
        self.cv = threading.Condition()
        self.waiting_for = 0  # the seq whose answer the loop waits for
        self.answer = None  # tau answering `waiting_for`
        self.answered = -1  # highest seq answered (a second answer is stale)
        self.published = {}  # seq -> monotonic time of its first publication (latency)
        self.latency_us = collections.deque(maxlen=4096)
        self.controller_alive = False
        self.controller_seen = False
        self.done = threading.Event()
        self.c = dict(
            torques_received=0,
            torques_dropped=0,
            torques_stale=0,
            deadline_misses=0,
            watchdog_trips=0,
            torques_foreign=0,
        )
        # --controller-id: torques are believed only from that session; without it, from the
        # session of the first torque believed, until it is silent for the lockstep timeout
        # (the plant's bound on a controller's silence; docs/protocol.md).
        self.controller_id = (
            tilting_source.id_bytes(args.controller_id) if args.controller_id else None
        )
        self.pin = tilting_source.SourcePin(
            self.controller_id, lapse=args.lockstep_timeout_ms * 1e-3
        )
        self.status_state = STARTING
        self.fault = ""
        self.log_bad = RateLimitedLog(f"{self.prefix}/controller/torque")
        self.sensor = Sensor(
            noise=(args.noise_alpha, args.noise_beta, args.noise_alpha_dot, args.noise_beta_dot),
            encoder_counts=args.encoder_counts,
            seed=args.seed,
            angles_only=args.measure == "angles",
        )
        # What was measured for a seq (measured once: a re-publication sends the same numbers):
        # (seq, t, y, payload), and (t, alpha, beta) of the sample before (the safe mode's rates).
        self.sample = None
        self.previous_angles = None

    # -- callbacks (zenoh threads) ------------------------------------------------------------

    def on_torque(self, sample):
        now = time.monotonic()
        source = tilting_source.source_of(sample)
        with self.cv:
            admitted = self.pin.admits(source, now)
            if not admitted:
                self.c["torques_received"] += 1
                self.c["torques_foreign"] += 1
                pinned = tilting_source.id_text(self.pin.pinned)
        if not admitted:
            self.log_bad(f"TorqueCommand from a foreign source, not the controller's session {pinned}")
            return
        try:
            seq, tau = unpack_torque(sample.payload.to_bytes())
            if abs(tau) > self.args.max_torque:
                raise ValueError(
                    f"TorqueCommand.tau = {tau} exceeds --max-torque {self.args.max_torque} N m"
                )
        except ValueError as e:
            with self.cv:
                self.c["torques_received"] += 1
                self.c["torques_dropped"] += 1
            self.log_bad(e)
            return
        with self.cv:
            self.pin.believe(source, now)
            self.c["torques_received"] += 1
            if seq == self.waiting_for and seq > self.answered:
                self.answer, self.answered = tau, seq
                t_pub = self.published.get(seq)
                if t_pub is not None:
                    self.latency_us.append((now - t_pub) * 1e6)
                self.cv.notify_all()
            else:
                self.c["torques_stale"] += 1

    def on_controller_alive(self, sample):
        alive = sample.kind == self.zenoh.SampleKind.PUT
        with self.cv:
            self.controller_alive = alive
            self.controller_seen |= alive
            self.cv.notify_all()
        what = "appeared" if alive else "disappeared"
        print(f"plant.py: controller {what} ({sample.key_expr})", file=sys.stderr, flush=True)

    # -- publishing ---------------------------------------------------------------------------

    def status_bytes(self, sim, seq):
        with self.cv:
            lat = sorted(self.latency_us)
            c = dict(self.c)
            state = self.status_state
        return pack_status(
            (
                seq,
                sim.t,
                state,
                sim.mode,
                sim.tilts,
                seq,  # steps = periods done
                c["torques_received"],
                c["torques_dropped"],
                c["torques_stale"],
                c["deadline_misses"],
                c["watchdog_trips"],
                0.0,  # jitter p50 (lockstep: no clock to jitter against)
                0.0,  # jitter p99
                0.0,  # max overrun
                percentile(lat, 0.5),
                percentile(lat, 0.99),
                0,  # torques late: lockstep applies only the answer to the current state
                0,  # torques lost
                0,  # torques reordered
                0.0,  # age p50, periods: always 0 in lockstep
                0.0,  # age p99
                0.0,  # age max
            ),
            self.fault,
        )

    def measured(self, seq, sim):
        """(y, payload): what the sensors measured for `seq` (measured at its first use)."""
        if self.sample is None or self.sample[0] != seq:
            if self.sample is not None:
                _, t0, y0, _ = self.sample
                self.previous_angles = (t0, y0[0], y0[1])
            y = self.sensor.measure(sim.x)
            payload = pack_state(seq, sim.t, sim.mode, y, self.sensor.measured)
            self.sample = (seq, sim.t, y, payload)
        return self.sample[2], self.sample[3]

    def publish_state(self, seq, sim):
        """Publishes state `seq`; from now on only a torque answering it is taken (set before
        the put, so that an answer arriving at once is not mistaken for a stale one)."""
        with self.cv:
            self.waiting_for = seq
            self.published.setdefault(seq, time.monotonic())
            self.published.pop(seq - 2, None)
        self.pub_state.put(self.measured(seq, sim)[1])

    def set_state(self, state, sim, seq):
        """Changes Status.state and publishes the status at once."""
        with self.cv:
            changed = self.status_state != state
            self.status_state = state
        if changed:
            self.pub_status.put(self.status_bytes(sim, seq))

    # -- the loop ------------------------------------------------------------------------------

    def wait_for_answer(self, seq, sim, safe):
        """Waits for the torque answering `seq`, re-publishing the state every 100 ms. Returns
        tau, or None after the lockstep timeout (1 ms in safe mode), when the controller's
        token disappears, or at Ctrl-C."""
        timeout = 1e-3 if safe else self.args.lockstep_timeout_ms * 1e-3
        end = time.monotonic() + timeout
        next_repub = time.monotonic() + 0.1
        with self.cv:
            while True:
                if self.answered == seq:
                    return self.answer
                if self.done.is_set() or (self.controller_seen and not self.controller_alive):
                    return None
                now = time.monotonic()
                if now >= end:
                    return None
                if now >= next_repub:
                    self.cv.release()
                    try:
                        self.pub_state.put(self.measured(seq, sim)[1])
                    finally:
                        self.cv.acquire()
                    next_repub = now + 0.1
                self.cv.wait(min(end, next_repub) - now)

    def wait_for_controller(self, sim):
        """Publishes state 0 every 100 ms until the controller's token appears or state 0 is
        answered (a controller without a token works too)."""
        while not self.done.is_set():
            self.publish_state(0, sim)
            with self.cv:
                if self.controller_alive or self.answered == 0:
                    return
                self.cv.wait(0.1)
                if self.controller_alive or self.answered == 0:
                    return

    def safe_torque(self, sim):
        if self.args.safe_mode == "zero":
            return 0.0
        # A critically damped computed-torque PD towards beta = pi/2, beta_dot = 0, on the
        # measured state (rates by a backward difference when only the angles are measured).
        y = self.measured(self.waiting_for, sim)[0]
        x = state_for_safe_mode(y, self.sensor.angles_only, sim.t, self.previous_angles)
        v = self.args.safe_kp * (math.pi / 2 - x[1]) - self.args.safe_kd * x[3]
        return torque_for_beta_ddot(sim.p, sim.mode, x, v)

    def run(self, sim):
        z, a = self.zenoh, self.args
        cfg = session_config(z, a.listen, a.connect)
        if a.zenoh_id:
            cfg.insert_json5("id", json.dumps(a.zenoh_id))
        session = z.open(cfg)
        # Lockstep: a state must arrive (it is re-sent after 100 ms without an answer anyway), so
        # these block; a real-time plant's drop on a congested link (docs/protocol.md).
        rt = dict(congestion_control=z.CongestionControl.BLOCK, priority=z.Priority.REAL_TIME)
        data = dict(congestion_control=z.CongestionControl.BLOCK, priority=z.Priority.DATA)
        # Every put names this session (the TSRC attachment of docs/protocol.md).
        pub = tilting_source.SourcedPublisher
        self.pub_state = pub(session, f"{self.prefix}/plant/state", express=True, **rt)
        self.pub_event = pub(session, f"{self.prefix}/plant/event", **data)
        self.pub_status = pub(session, f"{self.prefix}/plant/status", **data)
        sub = session.declare_subscriber(f"{self.prefix}/controller/torque", self.on_torque)
        watch = session.liveliness().declare_subscriber(
            f"{self.prefix}/alive/controller", self.on_controller_alive, history=True
        )
        # Declared last: a peer that sees the token can talk to us at once.
        token = session.liveliness().declare_token(f"{self.prefix}/alive/plant")
        print(
            f"plant.py: robot {a.robot}, lockstep, period {a.period} s, duration {a.duration} s, "
            f"RK4 step {a.step} s, measure {a.measure}; listen {a.listen}",
            file=sys.stderr,
            flush=True,
        )

        record = open(a.record, "w", encoding="utf-8") if a.record else None
        if record:
            record.write("seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau\n")
        seq = 0
        status_stop = threading.Event()

        def status_loop():  # 10 Hz
            while not status_stop.wait(0.1):
                self.pub_status.put(self.status_bytes(sim, seq))

        threading.Thread(target=status_loop, daemon=True).start()
        self.pub_status.put(self.status_bytes(sim, 0))
        n = math.inf if a.duration is None else round(a.duration / a.period)
        result, exit_code = "stopped", 0
        try:
            if not a.no_wait:
                self.wait_for_controller(sim)
            safe = False
            self.set_state(RUNNING, sim, seq)
            while not self.done.is_set():
                if seq > 0 or a.no_wait:  # (state 0 went out while waiting for the controller)
                    self.publish_state(seq, sim)
                if seq >= n:
                    result = "completed"
                    break
                tau = self.wait_for_answer(seq, sim, safe)
                if self.done.is_set():
                    break
                if tau is None:  # no answer: the safe-mode torque
                    with self.cv:
                        self.c["deadline_misses"] += 1
                        if not safe:
                            self.c["watchdog_trips"] += 1
                    if not safe:
                        print(f"plant.py: safe mode at seq {seq}", file=sys.stderr, flush=True)
                    safe = True
                    self.set_state(SAFE, sim, seq)
                    tau = self.safe_torque(sim)
                elif safe:
                    safe = False
                    self.set_state(RUNNING, sim, seq)
                if record:
                    record.write(f"{seq},{sim.t!r},{sim.mode},{','.join(map(repr, sim.x))},{tau!r}\n")
                t_next = (seq + 1) * a.period  # a product, not a running sum, which would drift
                if a.duration is not None and t_next >= a.duration - 1e-9 * a.period:
                    t_next = a.duration  # the last period is cut at the duration
                try:
                    events = sim.advance(tau, t_next)
                except Fault as f:
                    for ev in sim.transitions:  # the events up to the fault
                        self.pub_event.put(pack_event(seq, ev))
                    self.fault = str(f)
                    print(f"plant.py: fault: {f}", file=sys.stderr, flush=True)
                    result, exit_code = "faulted", 3
                    break
                for ev in events:
                    self.pub_event.put(pack_event(seq, ev))
                seq += 1
        finally:
            if record:
                if result == "completed":
                    record.write(f"{seq},{sim.t!r},{sim.mode},{','.join(map(repr, sim.x))},\n")
                record.close()
            status_stop.set()
            self.set_state(FAULTED if exit_code == 3 else STOPPED, sim, seq)
            token.undeclare()
            watch.undeclare()
            sub.undeclare()
            for pub in (self.pub_state, self.pub_event, self.pub_status):
                pub.undeclare()
            session.close()
        with self.cv:
            lat = sorted(self.latency_us)
            c = dict(self.c)
        peaks = list(sim.peaks)
        if sim.peak_in_progress() is not None:
            peaks.append(sim.peak_in_progress())
        summary = dict(
            result=result,
            fault=self.fault or None,
            clock="lockstep",
            period=a.period,
            seq=seq,
            time=sim.t,
            mode=MODE_NAMES[sim.mode],
            x=list(sim.x),
            steps=seq,
            tilts=sim.tilts,
            joint_events=sim.joint_events,
            joint=JOINT_NAMES[sim.joint],
            measure=a.measure,
            **c,
            latency_us=dict(
                p50=percentile(lat, 0.5),
                p99=percentile(lat, 0.99),
                max=lat[-1] if lat else 0.0,
                count=len(lat),
            ),
            tilt_peaks=[list(pk) for pk in peaks[-256:]],
        )
        print(json.dumps(summary), flush=True)
        return exit_code


def parse_x0(text):
    try:
        v = [float(s) for s in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 4 or not all(math.isfinite(u) for u in v):
        raise argparse.ArgumentTypeError("expected four finite numbers A,B,AD,BD")
    return v


class ArgumentParser(argparse.ArgumentParser):
    """Bad arguments exit with 1, as `tilting-plant` does (argparse's own convention is 2)."""

    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(1, f"{self.prog}: error: {message}\n")


def main(argv=None):
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="demo", help="key prefix tilting/{robot}/... (default demo)")
    ap.add_argument("--listen", action="append", help="endpoint, repeatable (default tcp/127.0.0.1:7447)")
    ap.add_argument("--connect", action="append", help="endpoint, repeatable (default none)")
    ap.add_argument("--period", type=float, default=1e-3, help="control period h, s (default 0.001)")
    ap.add_argument("--duration", type=float, help="plant time to run, s (default: until Ctrl-C)")
    ap.add_argument("--mode", choices=["flat", "left", "right"], default="left")
    ap.add_argument(
        "--x0",
        type=parse_x0,
        help="initial alpha,beta,alpha_dot,beta_dot (default: the start of the paper's orbit)",
    )
    ap.add_argument("--impact", choices=["paper", "striking-edge"], default="paper")
    ap.add_argument(
        "--params",
        help="TOML file with m_f, m_l, l, f, g, l_c, i_l, j_m, n_g, b_v, tau_c (default the paper's)",
    )
    ap.add_argument(
        "--measure",
        choices=["full", "angles"],
        default="full",
        help="what the state carries: full (angles and rates, measured = 15) or angles (the "
        "angles only, measured = 3: encoders, no velocity sensor; the controller estimates them)",
    )
    for flag, unit in zip(NOISE_FLAGS, ("rad", "rad", "rad/s", "rad/s")):
        ap.add_argument(
            flag, type=float, default=0.0, help=f"sensor noise standard deviation, {unit} (default 0)"
        )
    ap.add_argument(
        "--encoder-counts", type=int, help="encoder resolution of both angles, counts per turn"
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    ap.add_argument("--step", type=float, default=1e-4, help="largest RK4 step, s (default 1e-4)")
    ap.add_argument("--max-torque", type=float, default=116.5, help="refuse |tau| above, N m")
    ap.add_argument("--lockstep-timeout-ms", type=float, default=1000.0)
    ap.add_argument("--safe-mode", choices=["zero", "hold"], default="hold")
    ap.add_argument("--safe-kp", type=float, default=25.0)
    ap.add_argument("--safe-kd", type=float, default=10.0)
    ap.add_argument("--record", help="CSV of every sample: seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau")
    ap.add_argument("--no-wait", action="store_true", help="start without waiting for a controller")
    ap.add_argument(
        "--zenoh-id",
        type=tilting_source.zenoh_id_arg,
        help="this session's zenoh id, 1 to 32 hex digits (default random); attached to every put",
    )
    ap.add_argument(
        "--controller-id",
        type=tilting_source.zenoh_id_arg,
        help="believe torques only from this zenoh session (default: the session of the first "
        "torque believed, until it is silent for --lockstep-timeout-ms)",
    )
    ap.add_argument("--self-test", action="store_true", help="check encodings and model, then exit")
    args = ap.parse_args(argv)
    if args.self_test:
        self_test()
        return 0
    if not ROBOT_RE.match(args.robot):
        ap.error(f"--robot {args.robot!r}: allowed characters are [A-Za-z0-9_-], non-empty")
    if not (1e-4 <= args.period <= 10.0):
        ap.error(f"--period {args.period}: allowed 1e-4 to 10 s")
    if args.duration is not None and not (0.0 < args.duration and args.duration / args.period <= 1e9):
        ap.error(f"--duration {args.duration}: allowed > 0 and at most 1e9 periods")
    if not (0.0 < args.step <= args.period):
        ap.error(f"--step {args.step}: allowed > 0 and at most the period")
    if not (1.0 <= args.lockstep_timeout_ms <= 60000.0):
        ap.error("--lockstep-timeout-ms: allowed 1 to 60000")
    for flag in NOISE_FLAGS:
        v = getattr(args, flag[2:].replace("-", "_"))
        if not (math.isfinite(v) and 0.0 <= v <= MAX_SIGMA):
            unit = "rad/s" if flag.endswith("-dot") else "rad"
            ap.error(f"{flag} {v}: allowed a standard deviation in {unit} in [0, {MAX_SIGMA:g}]")
    if args.encoder_counts is not None and not (
        COUNTS_RANGE[0] <= args.encoder_counts <= COUNTS_RANGE[1]
    ):
        ap.error(
            f"--encoder-counts {args.encoder_counts}: allowed counts per revolution in "
            f"[{COUNTS_RANGE[0]}, {COUNTS_RANGE[1]}]"
        )
    args.listen = args.listen or ["tcp/127.0.0.1:7447"]
    args.connect = args.connect or []
    mode = {"flat": FLAT, "left": LEFT, "right": RIGHT}[args.mode]
    x0 = args.x0 or (0.0, math.pi / 2 - 0.000214877415, 0.0, 0.498257789692)
    params = Params.from_toml(args.params) if args.params else Params()
    try:
        sim = HybridPlant(mode, x0, params=params, impact=args.impact, h_max=args.step)
    except ValueError as e:
        ap.error(f"--mode/--x0: {e}")

    import zenoh  # imported here so that --self-test runs without it

    node = Node(args, zenoh)

    def stop(_signum, _frame):
        node.done.set()
        with node.cv:
            node.cv.notify_all()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    return node.run(sim)


if __name__ == "__main__":
    sys.exit(main())
