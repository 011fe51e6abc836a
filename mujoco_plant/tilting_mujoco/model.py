"""The tilting robot in MuJoCo: the MJCF built from the parameters, the contact presets, and one
control period at a time under a held torque.

Geometry (MuJoCo's x-z plane, gravity along -z; docs/model.md's x right, y up): the plate is one
box of length 2f on three joints, slides `x` and `z` and the hinge `alpha` (axis -y, so CCW in
the x-z plane is positive, > 0 tilted over the LEFT edge); its mass m_f (inertia `i_f`, see
`Params.plate_inertia`) sits at the centre of the box's bottom face, so the bottom corners are
at the height of the mass and are the model's pivots exactly (an edge of spheres or capsules
rolls, and the pivot walks). The arm is a hinge `beta` at the plate's centre (axis -y, beta = 0
along the plate, pi/2 upright) with m_l at l_c (inertia i_l), viscous friction b_v (`damping`),
Coulomb friction tau_c (`frictionloss`) and the rotor as `armature` n_g^2 j_m plus j_m on the
plate (the cross term n_g j_m of I12 is left out: MuJoCo's armature has none); the motor
applies tau on beta. The arm does not collide.

The contact mode is sensed as a robot would: a touch sensor under each half of the plate sums
the ground's normal force there; a half carries the plate when its force exceeds 0.5 N (both:
flat, the left only: tilted left, the right only: tilted right). Debounced, as a contact switch
is: a half touches or leaves the ground once its force has stayed on the other side of 0.5 N for
0.3 ms. Without it the soft contact's edges flicker after a landing (an edge lifting for 0.1 ms,
touching again at a few newtons when the torque changes), which counted as landings and tilts of
1e-4 rad. A transition is dated at the first step of the change (its event's time and states);
the mode of a published state may lag it by up to 0.3 ms (MuJoCo computes the forces of the
state at the start of each step).
"""

import math
from dataclasses import dataclass, field

import mujoco

FLAT, LEFT, RIGHT = 0, 1, 2
MODE_NAMES = {FLAT: "flat", LEFT: "left", RIGHT: "right"}
# A plate half carries the plate when its normal force exceeds this (N).
CONTACT_THRESHOLD = 0.5
# Faults (as the Rust plant's): the plate at or beyond pi/2, or off the ground this long (s).
FALL_ANGLE = math.pi / 2
AIRBORNE_LIMIT = 0.05
# A half touches the ground again once its force stays above the threshold this long (s).
TOUCH_DEBOUNCE = 3e-4
# MuJoCo's warnings that mean its state is not to be trusted: it resets the state on a bad
# acceleration (and goes on as if nothing happened, with a robot back at its reference pose),
# so any of these ends the run with a fault instead.
DIVERGENCE_WARNINGS = (
    ("mjWARN_BADQACC", "bad acceleration: the simulation diverged and MuJoCo reset its state"),
    ("mjWARN_BADQVEL", "bad velocity (not finite or huge)"),
    ("mjWARN_BADQPOS", "bad position (not finite or huge)"),
    ("mjWARN_BADCTRL", "bad control (not finite)"),
    ("mjWARN_CONTACTFULL", "too many contacts for the arena"),
    ("mjWARN_CNSTRFULL", "too many constraints for the arena"),
)


INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")


# MuJoCo's warning texts, kept for the fault message instead of going to stderr and to a
# MUJOCO_LOG.TXT in the working directory.
_last_warning = [""]


def _on_warning(text):
    _last_warning[0] = text.strip()


mujoco.set_mju_user_warning(_on_warning)


@dataclass(frozen=True)
class Contact:
    """The contact settings: MuJoCo's `solref` (time constant s, damping ratio), `solimp`
    (impedance d0, d_width, width m, midpoint, power), the sliding friction coefficient, the
    time step (s) and the integrator. Set on both the ground and the plate (MuJoCo mixes the two geoms' settings;
    the defaults left on one of them made the plate sink 1.6 mm)."""

    solref: tuple = (0.001, 1.0)
    solimp: tuple = (0.99, 0.999, 0.0005, 0.5, 2.0)
    friction: float = 2.0
    timestep: float = 2e-4
    integrator: str = "RK4"

    def check(self):
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator {self.integrator!r}: allowed {', '.join(INTEGRATORS)}")
        if not (1e-6 <= self.timestep <= 1e-3):
            raise ValueError(f"timestep {self.timestep}: allowed 1e-6 to 1e-3 s")
        if self.solref[0] > 0 and self.solref[0] < 2 * self.timestep:
            raise ValueError(
                f"solref time constant {self.solref[0]} s: must be at least twice the time step "
                f"{self.timestep} s (MuJoCo would stiffen it silently)"
            )
        if not (self.friction >= 0.3):
            # At 0.2 the plate slips and the tilting stops (measured).
            raise ValueError(f"friction {self.friction}: allowed >= 0.3 (the plate slips below)")


# Named presets, both integrated with RK4 at 0.2 ms (5 steps per 1 ms period). "stiff": a 1 ms
# contact time constant, critically damped, hard impedance: the plate sinks 2.5e-8 m under the
# robot at rest, and follows our rigid model to 4e-7 rad between landings. "moderate": MuJoCo's
# own defaults (20 ms, solimp 0.9 0.95 0.001): it sinks 0.1 mm and rocks on its soft edges after
# each landing (about 60 small tilts of 3e-3 rad in 5 s of the orbit, against 12): for seeing
# how much the contact model matters, not for running the orbit.
PRESETS = {
    "stiff": Contact(),
    "moderate": Contact(solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001, 0.5, 2.0)),
}


def _v(values):
    return " ".join(repr(float(v)) for v in values)


def mjcf(p, contact):
    """The MJCF of robot `p` (Params) with the contact settings `contact` (Contact)."""
    f, lc = p.f, p.lc
    width, thick = 0.1, 0.01  # the plate's half-width (y) and half-thickness (z), m
    # MuJoCo needs a positive inertia on every axis; the out-of-plane ones do not matter.
    i_plate = p.plate_inertia() + p.j_m
    i_arm = max(p.i_l, 1e-9)
    c = f'solref="{_v(contact.solref)}" solimp="{_v(contact.solimp)}" friction="{contact.friction!r} 0.005 0.0001"'
    return f"""<mujoco model="tilting">
  <compiler angle="radian"/>
  <option timestep="{contact.timestep!r}" gravity="0 0 {-p.g!r}" integrator="{contact.integrator}" cone="elliptic" noslip_iterations="0">
    <flag energy="enable"/>
  </option>
  <worldbody>
    <geom name="ground" type="plane" size="20 1 0.1" condim="3" {c}/>
    <body name="plate" pos="{f!r} 0 0">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <joint name="alpha" type="hinge" axis="0 -1 0"/>
      <inertial pos="0 0 0" mass="{p.m_f!r}" diaginertia="{i_plate!r} {i_plate!r} {i_plate!r}"/>
      <geom name="plate" type="box" size="{f!r} {width!r} {thick!r}" pos="0 0 {thick!r}" condim="3" mass="0" {c}/>
      <site name="left" type="box" pos="{-f / 2!r} 0 0" size="{f / 2 + 1e-3!r} {width + 1e-3!r} 0.005"/>
      <site name="right" type="box" pos="{f / 2!r} 0 0" size="{f / 2 + 1e-3!r} {width + 1e-3!r} 0.005"/>
      <body name="arm">
        <joint name="beta" type="hinge" axis="0 -1 0" damping="{p.b_v!r}" frictionloss="{p.tau_c!r}" armature="{p.n_g**2 * p.j_m!r}"/>
        <inertial pos="{lc!r} 0 0" mass="{p.m_l!r}" diaginertia="{i_arm!r} {i_arm!r} {i_arm!r}"/>
        <geom type="capsule" fromto="0 0 0 {p.l!r} 0 0" size="0.02" contype="0" conaffinity="0" mass="0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="tau" joint="beta" gear="1"/>
  </actuator>
  <sensor>
    <touch name="left" site="left"/>
    <touch name="right" site="right"/>
  </sensor>
</mujoco>
"""


class Fault(Exception):
    """A fault of the model: fall, contact loss, MuJoCo diverging."""


@dataclass
class Transition:
    t: float
    frm: int
    to: int
    x_before: tuple
    x_after: tuple


def mode_of(on_l, on_r, previous):
    """The contact mode from which halves touch the ground; `previous` when neither does."""
    if on_l and on_r:
        return FLAT
    if on_l:
        return LEFT
    if on_r:
        return RIGHT
    return previous


@dataclass
class Peaks:
    """The extreme alpha of each tilt, as the Rust plant's `tilt_peaks`: recorded at the landing,
    or once alpha has turned back in the tilt (`in_progress`)."""

    done: list = field(default_factory=list)
    current: tuple | None = None  # (t, alpha) of the tilt under way

    def see(self, t, mode, alpha):
        """The state at the end of a period."""
        if mode == FLAT:
            self.close()
        elif self.current is None or abs(alpha) > abs(self.current[1]):
            self.current = (t, alpha)

    def close(self):
        """The tilt under way ended (a landing, seen at its step: the next tilt may start in
        the same period)."""
        if self.current is not None:
            self.done.append(self.current)
            self.current = None

    def all(self, t_now, alpha_now):
        out = list(self.done)
        if self.current is not None and abs(alpha_now) < abs(self.current[1]):
            out.append(self.current)
        return out


class MujocoPlant:
    """The robot in MuJoCo, advanced one control period at a time under a held torque."""

    def __init__(self, params, contact=PRESETS["stiff"], mode=LEFT, x0=None, settle=0.3):
        contact.check()
        self.p, self.contact = params, contact
        self.model = mujoco.MjModel.from_xml_string(mjcf(params, contact))
        self.data = mujoco.MjData(self.model)
        self.warn_ids = [(int(getattr(mujoco.mjtWarning, n)), n, why) for n, why in DIVERGENCE_WARNINGS]
        self.mode = mode
        # Which halves touch the ground (debounced), and for a half whose force is on the other
        # side of the threshold: since which step (t, x before, x after, steps so far).
        self.on = [mode != RIGHT, mode != LEFT]
        self.pending = [None, None]
        self.tilts = 0
        self.transitions = []  # of the period being advanced
        self.n_transitions = 0
        self.airborne_since = None
        self.airborne_steps = 0
        self.peaks = Peaks()
        x0 = (0.0, math.pi / 2 - 0.000214877415, 0.0, 0.498257789692) if x0 is None else x0
        if (mode == FLAT and (x0[0] != 0.0 or x0[2] != 0.0)) or (mode == LEFT and x0[0] < 0) or (
            mode == RIGHT and x0[0] > 0
        ):
            raise ValueError(f"state {x0} is not one of mode {MODE_NAMES[mode]}")
        self._place(x0, settle)

    def _place(self, x0, settle):
        """Puts the robot at x0 with its plate resting on the ground: the angles are held at x0
        (rates zero) while the plate's slides settle into the contact for `settle` s, then the
        rates are set and the clock starts at 0."""
        m, d = self.model, self.data
        alpha, beta, ad, bd = x0
        # The plate's centre where the pivot (the left corner, or the right one) is at x = 0 or 2f.
        sf = -self.p.f if self.mode == RIGHT else self.p.f
        pivot = 0.0 if self.mode != RIGHT else 2.0 * self.p.f
        d.qpos[:] = (pivot + sf * math.cos(alpha) - self.p.f, sf * math.sin(alpha), alpha, beta)
        d.qvel[:] = 0.0
        for _ in range(round(settle / m.opt.timestep)):
            mujoco.mj_step(m, d)
            d.qpos[2:4] = (alpha, beta)
            d.qvel[2:4] = 0.0
        d.qvel[:] = (0.0, 0.0, ad, bd)
        if self.mode != FLAT:
            # The pivot does not move: the centre's velocity is the rotation about it.
            d.qvel[0] = -sf * math.sin(alpha) * ad
            d.qvel[1] = sf * math.cos(alpha) * ad
        d.time = 0.0
        d.ctrl[0] = 0.0
        mujoco.mj_forward(m, d)
        self.check_warnings()
        for w in d.warning:
            w.number = 0

    @property
    def t(self):
        return self.data.time

    @property
    def x(self):
        q, v = self.data.qpos, self.data.qvel
        return (float(q[2]), float(q[3]), float(v[2]), float(v[3]))

    def forces(self):
        """The ground's normal force under the plate's left and right halves (N), as MuJoCo
        computed them at the start of the last step."""
        s = self.data.sensordata
        return float(s[0]), float(s[1])

    def energy(self):
        """Kinetic plus potential energy (J) of the last forward pass (the contact's spring energy
        is not in it)."""
        return float(self.data.energy[0] + self.data.energy[1])

    def check_warnings(self):
        w = self.data.warning
        for i, name, why in self.warn_ids:
            if w[i].number > 0:
                raise Fault(
                    f"MuJoCo {name} at t = {self.data.time:.4f} s: {why} ({_last_warning[0]}); "
                    f"a smaller time step or softer contact (--preset moderate) may help"
                )

    def check_airborne(self, t_s):
        if self.on[0] or self.on[1]:
            self.airborne_since = None
            return
        self.airborne_steps += 1
        if self.airborne_since is None:
            self.airborne_since = t_s
        elif t_s - self.airborne_since > AIRBORNE_LIMIT:
            raise Fault(f"contact loss: the plate has been off the ground since t = {self.airborne_since:.4f} s")

    def advance(self, tau, t_target):
        """Holds the motor torque `tau` (N m) until `t_target` (s); the mode transitions of the
        period (each at the step where its forces were first seen). Raises Fault."""
        m, d = self.model, self.data
        d.ctrl[0] = tau
        self.transitions = []
        h = m.opt.timestep
        n = max(1, round((t_target - d.time) / h))
        q, v, s = d.qpos, d.qvel, d.sensordata
        x_prev = None
        debounce = max(1, round(TOUCH_DEBOUNCE / h))
        for _ in range(n):
            t_s = d.time
            x_s = (float(q[2]), float(q[3]), float(v[2]), float(v[3]))
            mujoco.mj_step(m, d)
            first = None  # the step a change confirmed now began at
            for i, force in enumerate((s[0], s[1])):
                if (force > CONTACT_THRESHOLD) == self.on[i]:
                    self.pending[i] = None
                    continue
                pend = self.pending[i] or (t_s, x_prev or x_s, x_s, 0)
                pend = pend[:3] + (pend[3] + 1,)
                self.pending[i] = pend
                if pend[3] >= debounce:
                    self.on[i], self.pending[i] = not self.on[i], None
                    first = pend if first is None or pend[0] < first[0] else first
            self.check_airborne(t_s)
            to = mode_of(self.on[0], self.on[1], self.mode)
            if to != self.mode:
                t_e, xb, xa = first[:3] if first else (t_s, x_prev or x_s, x_s)
                self.transitions.append(Transition(t_e, self.mode, to, xb, xa))
                if self.mode != FLAT:
                    self.peaks.close()
                if self.mode == FLAT:
                    self.tilts += 1
                self.n_transitions += 1
                self.mode = to
            x_prev = x_s
        d.time = t_target  # n steps of h: the same time to round-off, kept on the grid exactly
        self.check_warnings()
        alpha = float(q[2])
        if not math.isfinite(alpha) or abs(alpha) >= FALL_ANGLE:
            raise Fault(f"fall: alpha = {alpha} rad at t = {t_target:.4f} s, at or beyond the fall angle")
        self.peaks.see(t_target, self.mode, alpha)
        return self.transitions
