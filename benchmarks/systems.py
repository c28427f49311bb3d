"""The benchmark's mechanisms written as a user would without symid: plain data.

The baselines (`baselines.py`) read these descriptions; symid reads the
mechanism files (the bundled slider-crank, `ladder.toml(...)`). The numbers
here are copied by hand from those files, so a baseline that agrees with the
exact torque also agrees with symid.

Bodies are indices 0..nb-1, ground is -1. A driver's angle f(t, m) is written
once over a math namespace `m` (numpy, sympy or casadi: anything with sin and
cos); the hand NumPy baseline also needs its two time derivatives by hand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from benchmarks.ladder import Ladder

GROUND = -1
TimeFn = Callable[[Any, Any], Any]


@dataclass(frozen=True)
class Body:
    mass: float
    inertia: float
    q0: tuple[float, float, float]


@dataclass(frozen=True)
class Revolute:
    """r_j + A_j sj - r_i - A_i si = 0 (2 rows)."""

    i: int
    j: int
    si: tuple[float, float]
    sj: tuple[float, float]


@dataclass(frozen=True)
class Translational:
    """Slot of body i through si along vi, pin sj of body j; phi_j - phi_i = theta0 (2 rows)."""

    i: int
    j: int
    si: tuple[float, float]
    vi: tuple[float, float]
    sj: tuple[float, float]
    theta0: float = 0.0


@dataclass(frozen=True)
class AngleDriver:
    """phi_j - phi_i - f(t) = 0 (1 row); fd, fdd: its derivatives, numbers only."""

    i: int
    j: int
    f: TimeFn
    fd: Callable[[float], float]
    fdd: Callable[[float], float]


Joint = Revolute | Translational | AngleDriver


@dataclass(frozen=True)
class PointForce:
    """Force F(t, m) = (Fx, Fy), global components, at s on a body."""

    body: int
    s: tuple[float, float]
    F: TimeFn


@dataclass(frozen=True)
class System:
    """A mechanism for the baselines; `motor` is the index of the driver joint
    whose torque on body j (`T_on_j = -lambda`) is the compared output."""

    name: str
    bodies: list[Body]
    joints: list[Joint]
    forces: list[PointForce] = field(default_factory=list)
    gravity: tuple[float, float] = (0.0, -9.81)
    motor: int = -1

    @property
    def ng(self) -> int:
        return 3 * len(self.bodies)

    def rows(self) -> list[int]:
        """First constraint row of each joint."""
        out, r = [], 0
        for jt in self.joints:
            out.append(r)
            r += 1 if isinstance(jt, AngleDriver) else 2
        return out

    @property
    def nc(self) -> int:
        return sum(1 if isinstance(jt, AngleDriver) else 2 for jt in self.joints)

    def q0(self) -> np.ndarray:
        return np.array([v for b in self.bodies for v in b.q0], dtype=float)


# --- the slider-crank: the numbers of symid/examples/slider_crank.toml -------------------

L1, L2 = 0.1, 0.3
M1, M2, M3 = 0.5, 1.0, 0.8
A_S, B_S = 0.06, 0.04
OMEGA = 2 * math.pi * 5
F_GAS = 100.0
G = 9.81


def slider_crank() -> System:
    bodies = [Body(M1, M1 * L1 ** 2 / 12, (L1 / 2, 0.0, 0.0)),
              Body(M2, M2 * L2 ** 2 / 12, (L1 + L2 / 2, 0.0, 0.0)),
              Body(M3, M3 * (A_S ** 2 + B_S ** 2) / 12, (L1 + L2, 0.0, 0.0))]
    joints: list[Joint] = [
        Revolute(GROUND, 0, (0.0, 0.0), (-L1 / 2, 0.0)),
        Revolute(0, 1, (L1 / 2, 0.0), (-L2 / 2, 0.0)),
        Revolute(1, 2, (L2 / 2, 0.0), (0.0, 0.0)),
        Translational(GROUND, 2, (0.0, 0.0), (1.0, 0.0), (0.0, 0.0), 0.0),
        AngleDriver(GROUND, 0, lambda t, m: OMEGA * t, lambda t: OMEGA, lambda t: 0.0),
    ]
    forces = [PointForce(2, (0.0, 0.0), lambda t, m: (-F_GAS * m.sin(OMEGA * t), 0.0 * t))]
    return System("slider_crank", bodies, joints, forces, (0.0, -G), motor=4)


def slider_crank_torque(t: np.ndarray) -> np.ndarray:
    """The exact motor torque of the slider-crank from its closed-form kinematics.

    theta = omega t; the rod angle beta = -asin(L1 sin theta / L2) and the
    slider x = L1 cos theta + L2 cos beta follow in closed form, so the
    kinetic and potential energy E(t) are explicit; ideal joints do no work,
    so tau omega = dE/dt - F_gas . v_slider. sympy differentiates E and mpmath
    evaluates it with 30 digits: independent of symid and of the baselines.
    """
    import mpmath
    import sympy as sp

    ts = sp.Symbol("t", real=True)
    th = OMEGA * ts
    beta = -sp.asin(L1 * sp.sin(th) / L2)
    px, py = L1 * sp.cos(th), L1 * sp.sin(th)
    crank = (px / 2, py / 2, th, M1, M1 * L1 ** 2 / 12)
    rod = (px + L2 / 2 * sp.cos(beta), py + L2 / 2 * sp.sin(beta), beta, M2, M2 * L2 ** 2 / 12)
    xs = px + L2 * sp.cos(beta)
    slider = (xs, sp.Integer(0), sp.Integer(0), M3, M3 * (A_S ** 2 + B_S ** 2) / 12)
    energy = sum(m * (sp.diff(x, ts) ** 2 + sp.diff(y, ts) ** 2) / 2 + j * sp.diff(a, ts) ** 2 / 2 + m * G * y
                 for x, y, a, m, j in (crank, rod, slider))
    load_power = -F_GAS * sp.sin(th) * sp.diff(xs, ts)
    tau = sp.lambdify(ts, (sp.diff(energy, ts) - load_power) / OMEGA, "mpmath")
    with mpmath.workdps(30):
        return np.array([float(tau(mpmath.mpf(float(v)))) for v in np.asarray(t, float)])


# --- the ladder: the numbers of benchmarks/ladder.py ------------------------------------

def ladder(n: int) -> System:
    """N parallelogram bays: rockers 0..N, then couplers N+1..2N (as the TOML orders them)."""
    lad = Ladder(n)
    a, b = lad.a, lad.b
    bodies = [Body(lad.m_r, lad.j_r, tuple(lad.q_exact(0.0)[3 * k:3 * k + 3])) for k in range(n + 1)]
    bodies += [Body(lad.m_c, lad.j_c, tuple(lad.q_exact(0.0)[3 * (n + 1 + k):3 * (n + 2 + k)])) for k in range(n)]
    joints: list[Joint] = [Revolute(GROUND, k, (k * b, 0.0), (-a / 2, 0.0)) for k in range(n + 1)]
    for k in range(n):
        c = n + 1 + k
        joints += [Revolute(k, c, (a / 2, 0.0), (-b / 2, 0.0)), Revolute(c, k + 1, (b / 2, 0.0), (a / 2, 0.0))]
    th0, amp, w = lad.theta0, lad.amp, lad.w
    joints.append(AngleDriver(GROUND, 0, lambda t, m: th0 + amp * m.sin(w * t),
                              lambda t: amp * w * math.cos(w * t), lambda t: -amp * w * w * math.sin(w * t)))
    return System(f"ladder_{n}", bodies, joints, [], (0.0, -lad.g), motor=len(joints) - 1)
