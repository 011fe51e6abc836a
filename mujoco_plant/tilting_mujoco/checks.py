"""Physical self-checks of the MuJoCo model (no zenoh): `python3 -m tilting_mujoco --self-test`,
and one pytest test each in mujoco_plant/tests. Each returns what it measured."""

import math

from .model import FLAT, LEFT, RIGHT, Fault, MujocoPlant
from .params import Params

H = 1e-3  # the control period the checks advance by (s)


def run(mode, x0, seconds, tau=0.0, params=Params()):
    """(t, mode, x, energy) at every period of a run under a constant torque."""
    sim = MujocoPlant(params, mode=mode, x0=x0)
    out = [(0.0, sim.mode, sim.x, sim.energy())]
    for k in range(round(seconds / H)):
        sim.advance(tau, (k + 1) * H)
        out.append((sim.t, sim.mode, sim.x, sim.energy()))
    return sim, out


def passive_tilt():
    """A plate tilted 0.03 rad over its left edge, arm upright, no torque: it falls back and
    lands. Until 2 ms before the landing the energy stays within 0.5 % of the kinetic energy it
    gains (the soft pivot's work; measured 0.08 % with RK4 at 0.2 ms); the landing
    loses energy (measured 0.24 J of the 0.27 J: the plate stops dead) and never gains."""
    sim, out = run(LEFT, (0.03, math.pi / 2, 0.0, 0.0), 0.4)
    landing = next(i for i, r in enumerate(out) if r[1] == FLAT)
    e0 = out[0][3]
    before = out[: landing - 2]
    drift = max(abs(r[3] - e0) for r in before)
    p = Params()
    # The kinetic energy gained = the potential energy lost by the masses' fall.
    gained = kinetic(p, before[-1][2])
    lost = e0 - max(r[3] for r in out[landing:])
    assert 0.03 < out[landing][0] < 0.3, f"landed at {out[landing][0]} s"
    assert gained > 0.1, f"kinetic energy before the landing {gained} J"
    assert drift < 5e-3 * gained, f"energy drift {drift} J before the landing, of {gained} J"
    assert lost > 0.1 * gained, f"the landing lost {lost} J of {gained} J"
    return dict(landing_t=out[landing][0], drift=drift, kinetic=gained, lost=lost)


def kinetic(p, x):
    """The kinetic energy (J) of the tilted-left robot in state x (docs/model.md's mass matrix,
    with the plate's inertia MuJoCo gets)."""
    _, beta, ad, bd = x
    f, lc, cb = p.f, p.lc, math.cos(beta)
    m11 = p.m_f * f * f + p.m_l * (f * f + 2 * f * lc * cb + lc * lc) + p.plate_inertia() + p.i_l
    m12 = p.m_l * lc * (lc + f * cb) + p.i_l
    m22 = p.m_l * lc * lc + p.i_l
    return 0.5 * (m11 * ad * ad + 2 * m12 * ad * bd + m22 * bd * bd)


def mirror():
    """The mirror image of a left tilt (alpha -> -alpha, beta -> pi - beta, rates negated) is the
    right tilt: the same run within 1e-9 rad until the landing and after it."""
    x0 = (0.03, math.pi / 2 - 0.2, 0.0, 0.1)
    _, left = run(LEFT, x0, 0.3)
    _, right = run(RIGHT, (-x0[0], math.pi - x0[1], -x0[2], -x0[3]), 0.3)
    worst = 0.0
    for (tl, ml, xl, _), (tr, mr, xr, _) in zip(left, right):
        assert {ml, mr} in ({FLAT}, {LEFT, RIGHT}), f"modes {ml} {mr} at {tl}"
        m = (-xr[0], math.pi - xr[1], -xr[2], -xr[3])
        worst = max(worst, max(abs(a - b) for a, b in zip(xl, m)))
    assert any(r[1] == FLAT for r in left), "the left tilt landed"
    assert worst < 1e-9, f"mirror difference {worst}"
    return dict(worst=worst)


def flat_at_rest():
    """Flat, the arm held 0.3 rad off upright by its static torque m_l g l_c cos(beta): for 2 s
    the plate stays flat (no transition), the arm within 1e-6 rad, the plate within 1e-6 rad."""
    p = Params()
    beta = math.pi / 2 - 0.3
    sim, out = run(FLAT, (0.0, beta, 0.0, 0.0), 2.0, tau=p.m_l * p.g * p.lc * math.cos(beta))
    assert all(r[1] == FLAT for r in out) and sim.n_transitions == 0
    da = max(abs(r[2][0]) for r in out)
    db = max(abs(r[2][1] - beta) for r in out)
    assert da < 1e-6 and db < 1e-6, f"alpha moved {da}, beta {db}"
    return dict(alpha=da, beta=db)


def divergence_is_a_fault():
    """An absurd torque (1e9 N m, finite and below MuJoCo's 1e10 control bound) makes its
    accelerations blow up: a Fault naming mjWARN_BADQACC, not a silently reset state (MuJoCo
    resets the state and goes on: without the check the robot would be back at its reference
    pose)."""
    sim = MujocoPlant(Params(), mode=FLAT, x0=(0.0, math.pi / 2, 0.0, 0.0))
    try:
        for k in range(100):
            sim.advance(1e9, (k + 1) * H)
    except Fault as e:
        assert "mjWARN_BADQACC" in str(e), str(e)
        return dict(message=str(e))
    raise AssertionError("no fault after 100 periods of 1e9 N m")


CHECKS = (passive_tilt, mirror, flat_at_rest, divergence_is_a_fault)


def main():
    for check in CHECKS:
        print(f"{check.__name__}: {check()}")
    print("self-test passed")
    return 0
