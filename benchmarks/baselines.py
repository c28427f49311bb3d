"""Three ways a user would solve the same inverse dynamics without symid.

Every baseline does the full instant the way symid does: Newton positions
from a 2nd-order Taylor prediction off the previous instant (stop when
max |Phi| and the last max |dq| are both <= tol), qdot, qddot, the
multipliers, and the reaction (force and torque) of every joint on every
moving body, from which the motor torque `T_on_j = -lambda` is read.

- `HandNumpy`: hand-coded Jacobian blocks and gamma per joint type, a Python
  loop over joints, `np.linalg.solve` per solve.
- `SympyWhole`: the whole Phi(q, t) in sympy, `jacobian`, nu and gamma by
  differentiation, `lambdify` of each (dense matrices), the same Python loop.
- `CasadiWhole`: the whole Phi in CasADi SX, Jacobian and gamma by CasADi's
  AD, one `Function` per instant (a `fast_newton` rootfinder, the only Newton
  CasADi can generate C for, then `Linsol("qr")` solves), called from Python;
  `CasadiC` generates that Function to C and runs it in a C loop
  (`casadi_loop.c`, gcc -O2), timed inside C with clock_gettime. Both are in
  `casadi_baselines.py`, with the registry `APPROACHES` of all four.

Each has `setup()` -> seconds per phase, and `run(h, n, tol, budget_s)` ->
`Run`. All are single-threaded (the benchmark pins BLAS to one thread).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from benchmarks.systems import GROUND, AngleDriver, Revolute, System

MAX_NEWTON = 50


@dataclass
class Run:
    """What one timed run returns.

    Attributes:
        torque: the motor torque at each solved instant t_k = k h.
        seconds: wall time of each instant (Python loops), or empty.
        total_s: wall time of all solved instants.
        iterations: Newton iterations per instant, when known.
        error: why the run stopped early, if it failed.
    """

    torque: np.ndarray
    seconds: list[float] = field(default_factory=list)
    total_s: float = 0.0
    iterations: list[int] = field(default_factory=list)
    error: str | None = None


def _rot(phi: float) -> np.ndarray:
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s], [s, c]])


_R = np.array([[0.0, -1.0], [1.0, 0.0]])


class DenseModel:
    """A model evaluated with dense NumPy arrays; the shared Python loop drives it."""

    ng: int
    motor_index: int
    mass: np.ndarray

    def phi(self, q: np.ndarray, t: float) -> np.ndarray: ...
    def jac(self, q: np.ndarray, t: float) -> np.ndarray: ...
    def nu(self, q: np.ndarray, t: float) -> np.ndarray: ...
    def gamma(self, q: np.ndarray, qd: np.ndarray, t: float) -> np.ndarray: ...
    def applied(self, q: np.ndarray, t: float) -> np.ndarray: ...
    def reactions(self, q: np.ndarray, lam: np.ndarray, t: float) -> np.ndarray: ...

    def run(self, q0: np.ndarray, h: float, n: int, tol: float, budget_s: float) -> Run:
        """Up to n instants t_k = k h, stopping after budget_s seconds."""
        q, qd, qdd = q0.copy(), np.zeros(self.ng), np.zeros(self.ng)
        out = Run(np.zeros(0))
        torque = []
        start = time.perf_counter()
        for k in range(n):
            tick = time.perf_counter()
            t = k * h
            if k:
                q = q + h * qd + 0.5 * h * h * qdd
            step, it = math.inf, 0
            while True:
                phi = self.phi(q, t)
                if np.max(np.abs(phi)) <= tol and step <= tol:
                    break
                if it == MAX_NEWTON or not np.all(np.isfinite(phi)):
                    out.error = f"Newton did not converge at t = {t}"
                    break
                dq = np.linalg.solve(self.jac(q, t), -phi)
                q = q + dq
                step = float(np.max(np.abs(dq)))
                it += 1
            if out.error:
                break
            jac = self.jac(q, t)
            qd = np.linalg.solve(jac, self.nu(q, t))
            qdd = np.linalg.solve(jac, self.gamma(q, qd, t))
            lam = np.linalg.solve(jac.T, self.applied(q, t) - self.mass * qdd)
            torque.append(self.reactions(q, lam, t)[self.motor_index])
            now = time.perf_counter()
            out.seconds.append(now - tick)
            out.iterations.append(it)
            if now - start > budget_s:
                break
        out.total_s = time.perf_counter() - start
        out.torque = np.array(torque)
        return out


def _reaction_slots(system: System) -> tuple[list[tuple[int, int, str]], int]:
    """(joint, body, role) of every reaction triple (Fx, Fy, T), and the motor's T index."""
    slots = [(k, b, role) for k, jt in enumerate(system.joints)
             for role, b in (("i", jt.i), ("j", jt.j)) if b != GROUND]
    motor = slots.index((system.motor, system.joints[system.motor].j, "j"))
    return slots, 3 * motor + 2


# --- 1. hand NumPy ------------------------------------------------------------------

class HandNumpy(DenseModel):
    """Hand-derived Phi, Phi_q blocks, nu and gamma per joint type (the notes'
    tables), scalar arithmetic in a loop over joints, NumPy for the solves.

    Body states are read into lists with ground appended, so index -1 (ground)
    reads x = y = phi = 0 without a branch. For B s' = R A s' the code uses
    (-(A s')_y, (A s')_x).
    """

    def __init__(self, system: System) -> None:
        self.s = system
        self.ng, self.nc = system.ng, system.nc
        self.row0 = system.rows()
        self.slots, self.motor_index = _reaction_slots(system)

    def setup(self) -> dict[str, float]:
        tick = time.perf_counter()
        self.mass = np.array([v for b in self.s.bodies for v in (b.mass, b.mass, b.inertia)])
        self.weight = [(b.mass * self.s.gravity[0], b.mass * self.s.gravity[1]) for b in self.s.bodies]
        return {"derive": 0.0, "generate": time.perf_counter() - tick, "compile": 0.0}

    @staticmethod
    def _state(q: np.ndarray) -> tuple[list[float], ...]:
        """x, y, phi, cos phi, sin phi of every body, ground appended."""
        phi = q[2::3]
        return (q[0::3].tolist() + [0.0], q[1::3].tolist() + [0.0], phi.tolist() + [0.0],
                np.cos(phi).tolist() + [1.0], np.sin(phi).tolist() + [0.0])

    @staticmethod
    def _turn(c: float, s: float, p: tuple[float, float]) -> tuple[float, float]:
        return c * p[0] - s * p[1], s * p[0] + c * p[1]

    def phi(self, q: np.ndarray, t: float) -> np.ndarray:
        x, y, p, c, s = self._state(q)
        out = np.empty(self.nc)
        for r, jt in zip(self.row0, self.s.joints):
            i, j = jt.i, jt.j
            if isinstance(jt, AngleDriver):
                out[r] = p[j] - p[i] - jt.f(t, math)
                continue
            aix, aiy = self._turn(c[i], s[i], jt.si)
            ajx, ajy = self._turn(c[j], s[j], jt.sj)
            dx, dy = x[j] + ajx - x[i] - aix, y[j] + ajy - y[i] - aiy
            if isinstance(jt, Revolute):
                out[r], out[r + 1] = dx, dy
            else:
                vx, vy = self._turn(c[i], s[i], jt.vi)
                out[r], out[r + 1] = -vy * dx + vx * dy, p[j] - p[i] - jt.theta0
        return out

    def _blocks(self, jt: Any, x: list[float], y: list[float], c: list[float], s: list[float],
                ) -> list[tuple[int, list[tuple[float, float, float]], tuple[float, float]]]:
        """(body, rows of (Phi_x, Phi_y, Phi_phi), point s') of each role."""
        i, j = jt.i, jt.j
        if isinstance(jt, AngleDriver):
            return [(i, [(0.0, 0.0, -1.0)], (0.0, 0.0)), (j, [(0.0, 0.0, 1.0)], (0.0, 0.0))]
        aix, aiy = self._turn(c[i], s[i], jt.si)
        ajx, ajy = self._turn(c[j], s[j], jt.sj)
        if isinstance(jt, Revolute):
            return [(i, [(-1.0, 0.0, aiy), (0.0, -1.0, -aix)], jt.si),
                    (j, [(1.0, 0.0, -ajy), (0.0, 1.0, ajx)], jt.sj)]
        ax, ay = self._turn(c[i], s[i], jt.vi)
        nx, ny = -ay, ax
        dx, dy = x[j] + ajx - x[i] - aix, y[j] + ajy - y[i] - aiy
        return [(i, [(-nx, -ny, -(ax * dx + ay * dy) - (-nx * aiy + ny * aix)), (0.0, 0.0, -1.0)], jt.si),
                (j, [(nx, ny, -nx * ajy + ny * ajx), (0.0, 0.0, 1.0)], jt.sj)]

    def jac(self, q: np.ndarray, t: float) -> np.ndarray:
        x, y, _, c, s = self._state(q)
        out = np.zeros((self.nc, self.ng))
        for r, jt in zip(self.row0, self.s.joints):
            for b, rows, _ in self._blocks(jt, x, y, c, s):
                if b != GROUND:
                    for e, row in enumerate(rows):
                        out[r + e, 3 * b:3 * b + 3] = row
        return out

    def nu(self, q: np.ndarray, t: float) -> np.ndarray:
        out = np.zeros(self.nc)
        for r, jt in zip(self.row0, self.s.joints):
            if isinstance(jt, AngleDriver):
                out[r] = jt.fd(t)
        return out

    def gamma(self, q: np.ndarray, qd: np.ndarray, t: float) -> np.ndarray:
        x, y, _, c, s = self._state(q)
        vx, vy, w, _, _ = self._state(qd)
        out = np.zeros(self.nc)
        for r, jt in zip(self.row0, self.s.joints):
            i, j = jt.i, jt.j
            if isinstance(jt, AngleDriver):
                out[r] = jt.fdd(t)
                continue
            aix, aiy = self._turn(c[i], s[i], jt.si)
            ajx, ajy = self._turn(c[j], s[j], jt.sj)
            wi2, wj2 = w[i] ** 2, w[j] ** 2
            if isinstance(jt, Revolute):
                out[r], out[r + 1] = ajx * wj2 - aix * wi2, ajy * wj2 - aiy * wi2
                continue
            ax, ay = self._turn(c[i], s[i], jt.vi)
            nx, ny = -ay, ax
            dx, dy = x[j] + ajx - x[i] - aix, y[j] + ajy - y[i] - aiy
            ddx = vx[j] - ajy * w[j] - vx[i] + aiy * w[i]
            ddy = vy[j] + ajx * w[j] - vy[i] - aix * w[i]
            out[r] = (wi2 * (nx * dx + ny * dy) + 2 * w[i] * (ax * ddx + ay * ddy)
                      - nx * (aix * wi2 - ajx * wj2) - ny * (aiy * wi2 - ajy * wj2))
        return out

    def applied(self, q: np.ndarray, t: float) -> np.ndarray:
        out = np.zeros(self.ng)
        for b, (gx, gy) in enumerate(self.weight):
            out[3 * b] += gx
            out[3 * b + 1] += gy
        for f in self.s.forces:
            fx, fy = (float(v) for v in f.F(t, math))
            ax, ay = self._turn(math.cos(q[3 * f.body + 2]), math.sin(q[3 * f.body + 2]), f.s)
            out[3 * f.body] += fx
            out[3 * f.body + 1] += fy
            out[3 * f.body + 2] += -ay * fx + ax * fy
        return out

    def reactions(self, q: np.ndarray, lam: np.ndarray, t: float) -> np.ndarray:
        """F = -Phi_r^T lam, T = (B s')^T Phi_r^T lam - Phi_phi^T lam on every moving body."""
        x, y, _, c, s = self._state(q)
        lk = lam.tolist()
        out: list[float] = []
        for r, jt in zip(self.row0, self.s.joints):
            for b, rows, point in self._blocks(jt, x, y, c, s):
                if b == GROUND:
                    continue
                fx = sum(row[0] * lk[r + e] for e, row in enumerate(rows))
                fy = sum(row[1] * lk[r + e] for e, row in enumerate(rows))
                tp = sum(row[2] * lk[r + e] for e, row in enumerate(rows))
                px, py = self._turn(c[b], s[b], point)
                out += [-fx, -fy, -py * fx + px * fy - tp]
        return np.array(out)


# --- the whole system written once over a symbolic namespace (sympy or casadi) -------

def symbolic_phi(system: System, q: Any, t: Any, m: Any) -> list[Any]:
    """Every row of Phi(q, t); q indexable by coordinate, m has sin and cos."""
    def body(b: int) -> tuple[list[Any], Any]:
        return ([0, 0], 0) if b == GROUND else ([q[3 * b], q[3 * b + 1]], q[3 * b + 2])

    def rot(phi: Any, s: tuple[float, float]) -> list[Any]:
        c, sn = m.cos(phi), m.sin(phi)
        return [c * s[0] - sn * s[1], sn * s[0] + c * s[1]]

    rows: list[Any] = []
    for jt in system.joints:
        (ri, pi), (rj, pj) = body(jt.i), body(jt.j)
        if isinstance(jt, AngleDriver):
            rows.append(pj - pi - jt.f(t, m))
            continue
        ai, aj = rot(pi, jt.si), rot(pj, jt.sj)
        d = [rj[k] + aj[k] - ri[k] - ai[k] for k in range(2)]
        if isinstance(jt, Revolute):
            rows += d
        else:
            v = rot(pi, jt.vi)
            rows += [-v[1] * d[0] + v[0] * d[1], pj - pi - jt.theta0]
    return rows


def symbolic_applied(system: System, q: Any, t: Any, m: Any) -> list[Any]:
    out: list[Any] = [0] * system.ng
    for b, bd in enumerate(system.bodies):
        out[3 * b] += bd.mass * system.gravity[0]
        out[3 * b + 1] += bd.mass * system.gravity[1]
    for f in system.forces:
        fx, fy = f.F(t, m)
        phi = q[3 * f.body + 2]
        c, sn = m.cos(phi), m.sin(phi)
        bx, by = -sn * f.s[0] - c * f.s[1], c * f.s[0] - sn * f.s[1]
        out[3 * f.body] += fx
        out[3 * f.body + 1] += fy
        out[3 * f.body + 2] += bx * fx + by * fy
    return out


def _symbolic_reactions(system: System, q: Any, jac: Any, lam: Any, m: Any) -> list[Any]:
    """The reaction formula on the Jacobian's blocks (jac[r, c] indexable)."""
    slots, _ = _reaction_slots(system)
    row0 = system.rows()
    out: list[Any] = []
    for k, b, role in slots:
        jt = system.joints[k]
        r = row0[k]
        rows = 1 if isinstance(jt, AngleDriver) else 2
        s = (0.0, 0.0) if isinstance(jt, AngleDriver) else (jt.si if role == "i" else jt.sj)
        c, sn = m.cos(q[3 * b + 2]), m.sin(q[3 * b + 2])
        bs = (-sn * s[0] - c * s[1], c * s[0] - sn * s[1])
        fx = sum(jac[r + e, 3 * b] * lam[r + e] for e in range(rows))
        fy = sum(jac[r + e, 3 * b + 1] * lam[r + e] for e in range(rows))
        tp = sum(jac[r + e, 3 * b + 2] * lam[r + e] for e in range(rows))
        out += [-fx, -fy, bs[0] * fx + bs[1] * fy - tp]
    return out


# --- 2. sympy whole system + lambdify --------------------------------------------------

class SympyWhole(DenseModel):
    """The whole system in sympy; `lambdify` as a user would call it (no options)."""

    def __init__(self, system: System) -> None:
        self.s = system
        self.ng, self.nc = system.ng, system.nc
        _, self.motor_index = _reaction_slots(system)
        self.mass = np.array([v for b in system.bodies for v in (b.mass, b.mass, b.inertia)])

    def setup(self) -> dict[str, float]:
        import sympy as sp

        tick = time.perf_counter()
        q = sp.Matrix(sp.symbols(f"q0:{self.ng}", real=True))
        qd = sp.Matrix(sp.symbols(f"qd0:{self.ng}", real=True))
        lam = sp.Matrix(sp.symbols(f"lam0:{self.nc}", real=True))
        t = sp.Symbol("t", real=True)
        phi = sp.Matrix(symbolic_phi(self.s, q, t, sp))
        jac = phi.jacobian(q)
        phi_t = phi.diff(t)
        jqd = jac * qd
        gamma = -jqd.jacobian(q) * qd - 2 * jqd.diff(t) - phi_t.diff(t)
        applied = sp.Matrix(symbolic_applied(self.s, q, t, sp))
        reac = sp.Matrix(_symbolic_reactions(self.s, q, jac, lam, sp))
        derived = time.perf_counter()
        self._phi = sp.lambdify((q, t), phi, "numpy")
        self._jac = sp.lambdify((q, t), jac, "numpy")
        self._nu = sp.lambdify((q, t), -phi_t, "numpy")
        self._gamma = sp.lambdify((q, qd, t), gamma, "numpy")
        self._applied = sp.lambdify((q, t), applied, "numpy")
        self._reac = sp.lambdify((q, lam, t), reac, "numpy")
        return {"derive": derived - tick, "generate": time.perf_counter() - derived, "compile": 0.0}

    def phi(self, q: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self._phi(q, t), dtype=float).ravel()

    def jac(self, q: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self._jac(q, t), dtype=float)

    def nu(self, q: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self._nu(q, t), dtype=float).ravel()

    def gamma(self, q: np.ndarray, qd: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self._gamma(q, qd, t), dtype=float).ravel()

    def applied(self, q: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self._applied(q, t), dtype=float).ravel()

    def reactions(self, q: np.ndarray, lam: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self._reac(q, lam, t), dtype=float).ravel()


# --- 3. CasADi whole system, from Python and generated to C --------------------------


