"""A scalable mechanism with an exact answer: a ladder of N parallelogram four-bars.

N + 1 equal rockers (length a, mass m_r) are pinned to ground at x = k b,
k = 0..N; coupler k (length b, mass m_c) joins the tip of rocker k to the tip
of rocker k + 1. An angle driver turns rocker 0: theta(t) = theta0 + A sin(w t)
from the +x axis, with theta0 = pi/2 and A = 0.6 rad, so the rockers swing
between 33 and 147 degrees and never reach the change points theta = 0, pi
where a parallelogram's Jacobian is singular. Gravity (0, -g).

2N + 1 bodies, ng = 6N + 3; 3N + 1 revolutes (6N + 2 rows) plus the driver.

Closed form. Every parallelogram keeps its coupler parallel to the ground
line, so all rockers share the angle theta and every coupler translates
(phi = 0). Rocker k's centre of mass is (k b + a/2 cos theta, a/2 sin theta)
and coupler k's is ((k + 1/2) b + a cos theta, a sin theta). With J_r the
rockers' inertia about their centre of mass:

    kinetic   T = 1/2 I_eff thetadot^2,
              I_eff = (N + 1) (J_r + m_r a^2 / 4) + N m_c a^2
    potential V = g a ((N + 1) m_r / 2 + N m_c) sin theta = G_eff sin theta

I_eff is constant, so Lagrange's equation for the single coordinate gives
the motor torque (the driver's `T_j`, the torque it applies to rocker 0):

    tau = I_eff thetaddot + G_eff cos theta.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Ladder:
    """Dimensions (SI) and the drive of an N-bay ladder; the defaults are what the benchmark uses."""

    n: int
    a: float = 0.5          # rocker length, m
    b: float = 0.4          # bay width = coupler length, m
    m_r: float = 1.0        # rocker mass, kg
    m_c: float = 0.5        # coupler mass, kg
    g: float = 9.81         # m/s^2
    theta0: float = math.pi / 2
    amp: float = 0.6        # rad
    w: float = 2 * math.pi  # rad/s: one swing per second
    t1: float = 1.0
    x0: float = 0.0         # x of the first pivot: far from the origin, coordinates are large

    @property
    def ng(self) -> int:
        return 6 * self.n + 3

    @property
    def j_r(self) -> float:
        return self.m_r * self.a ** 2 / 12

    @property
    def j_c(self) -> float:
        return self.m_c * self.b ** 2 / 12

    @property
    def i_eff(self) -> float:
        return (self.n + 1) * (self.j_r + self.m_r * self.a ** 2 / 4) + self.n * self.m_c * self.a ** 2

    @property
    def g_eff(self) -> float:
        return self.g * self.a * ((self.n + 1) * self.m_r / 2 + self.n * self.m_c)

    def theta(self, t: np.ndarray) -> np.ndarray:
        return self.theta0 + self.amp * np.sin(self.w * np.asarray(t, float))

    def thetadot(self, t: np.ndarray) -> np.ndarray:
        return self.amp * self.w * np.cos(self.w * np.asarray(t, float))

    def thetaddot(self, t: np.ndarray) -> np.ndarray:
        return -self.amp * self.w ** 2 * np.sin(self.w * np.asarray(t, float))

    def torque(self, t: np.ndarray) -> np.ndarray:
        """The exact motor torque at times t (N m)."""
        return self.i_eff * self.thetaddot(t) + self.g_eff * np.cos(self.theta(t))

    def q_exact(self, t: float) -> np.ndarray:
        """The exact configuration at t, size ng: rockers then couplers."""
        th = float(self.theta(t))
        c, s = math.cos(th), math.sin(th)
        rockers = [[self.x0 + k * self.b + self.a / 2 * c, self.a / 2 * s, th] for k in range(self.n + 1)]
        couplers = [[self.x0 + (k + 0.5) * self.b + self.a * c, self.a * s, 0.0] for k in range(self.n)]
        return np.array(rockers + couplers, dtype=float).ravel()


def name(n: int) -> str:
    return f"ladder_{n}"


def toml(lad: Ladder, steps: int = 1001) -> str:
    """The mechanism file of an N-bay ladder (parameters kept symbolic)."""
    n = lad.n
    out = [
        f"# A ladder of {n} parallelogram four-bars in series (symid benchmark; see benchmarks/ladder.py).",
        "", "[mechanism]", f'name = "{name(n)}"', f"gravity = [0.0, {-lad.g!r}]",
        "", "[parameters]",
        f"a = {lad.a!r}", f"b = {lad.b!r}", f"m_r = {lad.m_r!r}", f"m_c = {lad.m_c!r}",
        f"theta0 = {lad.theta0!r}", f"A = {lad.amp!r}", f"w = {lad.w!r}", *([f"x0 = {lad.x0!r}"] if lad.x0 else []),
        "", "[analysis]", 'kind = "inverse_dynamics"', "t0 = 0.0", f"t1 = {lad.t1!r}", f"steps = {steps}",
    ]
    shift = "x0 + " if lad.x0 else ""
    for k in range(n + 1):
        out += ["", "[[body]]", f'name = "rocker{k}"', 'mass = "m_r"', 'inertia = "m_r*a^2/12"',
                f'q0 = ["{shift}{k}*b + a/2*cos(theta0)", "a/2*sin(theta0)", "theta0"]']
    for k in range(n):
        out += ["", "[[body]]", f'name = "coupler{k}"', 'mass = "m_c"', 'inertia = "m_c*b^2/12"',
                f'q0 = ["{shift}({k} + 0.5)*b + a*cos(theta0)", "a*sin(theta0)", 0.0]']
    for k in range(n + 1):
        out += ["", "[[constraint]]", f'name = "pivot{k}"', 'type = "revolute"', 'i = "ground"',
                f'j = "rocker{k}"', f'si = ["{shift}{k}*b", 0.0]', 'sj = ["-a/2", 0.0]']
    for k in range(n):
        out += ["", "[[constraint]]", f'name = "left{k}"', 'type = "revolute"', f'i = "rocker{k}"',
                f'j = "coupler{k}"', 'si = ["a/2", 0.0]', 'sj = ["-b/2", 0.0]',
                "", "[[constraint]]", f'name = "right{k}"', 'type = "revolute"', f'i = "coupler{k}"',
                f'j = "rocker{k + 1}"', 'si = ["b/2", 0.0]', 'sj = ["a/2", 0.0]']
    out += ["", "[[constraint]]", 'name = "motor"', 'type = "relative_angle_driver"', 'i = "ground"',
            'j = "rocker0"', 'f = "theta0 + A*sin(w*t)"', "C = 0.0", ""]
    return "\n".join(out)


def write(n: int, folder: str | Path, steps: int = 1001, **dims: float) -> Path:
    """Write `ladder_<n>.toml` (dimensions: the defaults of `Ladder` unless
    given) into folder and return its path."""
    path = Path(folder) / f"{name(n)}.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(toml(Ladder(n, **dims), steps))
    return path


if __name__ == "__main__":
    import sys

    for arg in sys.argv[1:] or ["4"]:
        print(write(int(arg), "."))
