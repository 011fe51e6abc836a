"""The robot's parameters: the keys of docs/model.md, read from the same TOML file as the Rust
workspace's `--params` (plant/src/params.rs), with the same defaults (the paper's robot)."""

import math
import tomllib
from dataclasses import dataclass, fields

# The landing law and the restitution are the Rust model's; in MuJoCo the contact decides how a
# landing goes, so they are accepted (a file written for the Rust plant works here) and ignored.
IGNORED = ("impact", "restitution")


@dataclass(frozen=True)
class Params:
    m_f: float = 1.0  # kg, the plate's mass (at its centre)
    m_l: float = 1.0  # kg, the arm's mass (at l_c along the arm)
    l: float = 2.0  # m, the arm's length
    f: float = 0.5  # m, half the plate's length
    g: float = 9.81  # m/s^2
    l_c: float | None = None  # m, the arm's centre of mass (None: the tip, l)
    i_l: float = 0.0  # kg m^2, the arm's inertia about its centre of mass
    j_m: float = 0.0  # kg m^2, the rotor's inertia
    n_g: float = 1.0  # the gear ratio
    b_v: float = 0.0  # N m s/rad, viscous joint friction
    tau_c: float = 0.0  # N m, Coulomb joint friction
    i_f: float = 0.0  # kg m^2, the plate's inertia about its centre (0: the paper's point mass)

    @property
    def lc(self):
        return self.l if self.l_c is None else self.l_c

    @staticmethod
    def from_toml(path):
        """The file's parameters; ValueError naming the key and its allowed range."""
        with open(path, "rb") as fh:
            d = tomllib.load(fh)
        known = {f.name for f in fields(Params)}
        unknown = set(d) - known - set(IGNORED)
        if unknown:
            raise ValueError(f"{path}: unknown keys {sorted(unknown)}; allowed {sorted(known | set(IGNORED))}")
        p = Params(**{k: float(v) for k, v in d.items() if k in known})
        p.check(path)
        return p

    def check(self, where="params"):
        for k in ("m_f", "m_l", "l", "f", "g", "n_g"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{where}: {k} = {v}; allowed: finite and > 0")
        for k in ("i_l", "j_m", "b_v", "tau_c", "i_f"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{where}: {k} = {v}; allowed: finite and >= 0")
        if not (math.isfinite(self.lc) and 0.0 < self.lc <= self.l):
            raise ValueError(f"{where}: l_c = {self.lc}; allowed: finite, > 0 and <= l")

    def plate_inertia(self):
        """The plate's inertia MuJoCo gets: `i_f` if > 0, else that of a uniform thin plate of
        mass m_f and length 2f, m_f (2f)^2 / 12 (0.083 kg m^2 for the paper's plate). A point-mass
        plate (i_f = 0) leaves the plate's hinge with almost no inertia of its own: the mass
        matrix's condition number reached 1.8e10, MuJoCo diverged and reset its state."""
        return self.i_f if self.i_f > 0.0 else self.m_f * (2.0 * self.f) ** 2 / 12.0

    def joint_inertia(self):
        """The arm's inertia about its joint, rotor included (kg m^2)."""
        return self.m_l * self.lc**2 + self.i_l + self.n_g**2 * self.j_m
