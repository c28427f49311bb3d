"""What Newton's tolerance and the predictor's order cost and buy.

symid's loops predict each instant's q with a 2nd-order Taylor step from the
previous one. Here the benchmark drives Newton itself so the order can vary:
order 0 starts from the previous q, 1 adds h qdot, 2 adds h^2/2 qddot. Two
drivers over the same C backend of one mechanism:

- `python_newton`: the Evaluator protocol (phi, phi_q, ...) with SciPy's LU,
  Newton as in `symid.solve` (stop when max |Phi| and the last max |dq| are
  both <= max(tol, 8 eps max(1, max |q|))).
- `compiled_instant`: the generated `<name>_instant` (Newton, qdot, qddot,
  lambda, reactions in C) called per instant through ctypes with the guess
  made in Python; its time is the ctypes call alone (about 1 us of it is
  the call itself).

Both return the Newton iterations per instant, the time per instant and the
motor torque, from which the caller computes the error.
"""

from __future__ import annotations

import ctypes
import time
from typing import Any

import numpy as np
import scipy.linalg as sla

from symid import api

EPS = float(np.finfo(float).eps)


def motor_reaction_index(study: api.Study, column: str = "motor.T_j") -> int:
    """Index of a reaction column within `Evaluator.reactions`' vector."""
    cols = study.columns()
    first = next(k for k, c in enumerate(cols) if c.endswith(".Fx_i"))
    return cols.index(column) - first


def _guess(order: int, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, h: float) -> np.ndarray:
    if order == 0:
        return q.copy()
    if order == 1:
        return q + h * qd
    return q + h * qd + 0.5 * h * h * qdd


def python_newton(study: api.Study, order: int, tol: float, n: int) -> dict[str, Any]:
    """n instants of the study's grid with a predictor of the given order."""
    ev, a = study.evaluator, study.analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    index = motor_reaction_index(study)
    mass = ev.mass()
    q, qd, qdd = study.q0(), np.zeros(study.layout.ng), np.zeros(study.layout.ng)
    iterations, seconds, torque = [], [], []
    for k in range(n):
        tick = time.perf_counter()
        t = a.t0 + k * h
        q = _guess(order, q, qd, qdd, h) if k else q
        step, it = np.inf, 0
        while True:
            phi = ev.phi(q, t)
            lim = max(tol, 8 * EPS * max(1.0, float(np.max(np.abs(q)))))
            if np.max(np.abs(phi)) <= lim and step <= lim:
                break
            if it == 50 or not np.all(np.isfinite(phi)):
                return {"error": f"Newton did not converge at t = {t}", "iterations": iterations,
                        "seconds": seconds, "torque": torque}
            dq = sla.lu_solve(sla.lu_factor(ev.phi_q(q, t), check_finite=False), -phi, check_finite=False)
            q = q + dq
            step = float(np.max(np.abs(dq)))
            it += 1
        lu = sla.lu_factor(ev.phi_q(q, t), check_finite=False)
        qd = sla.lu_solve(lu, ev.nu(q, t), check_finite=False)
        qdd = sla.lu_solve(lu, ev.gamma(q, qd, t), check_finite=False)
        lam = sla.lu_solve(lu, ev.applied(q, qd, t) - mass * qdd, trans=1, check_finite=False)
        torque.append(float(ev.reactions(q, lam, t)[index]))
        seconds.append(time.perf_counter() - tick)
        iterations.append(it)
    return {"error": None, "iterations": iterations, "seconds": seconds, "torque": torque}


def compiled_instant(study: api.Study, order: int, tol: float, n: int) -> dict[str, Any]:
    """The same with the C backend's `<name>_instant` doing each instant."""
    ev, a = study.evaluator, study.analysis
    fn = getattr(ev.lib, f"{study.mechanism.name}_instant")
    dbl, ptr, iptr = ctypes.c_double, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
    fn.argtypes = [dbl, ptr, dbl, ptr, ptr, ptr, ptr, ptr, iptr, ptr, iptr]
    meta, ng = ev.meta, study.layout.ng
    h = (a.t1 - a.t0) / (a.steps - 1)
    index = motor_reaction_index(study)
    q, qd, qdd = study.q0(), np.zeros(ng), np.zeros(ng)
    lam, reac = np.zeros(max(1, meta["nc"])), np.zeros(max(1, meta["nr"]))
    info = np.zeros(2, dtype=np.intc)
    p, work, iwork = ev.p, ev.work, ev.iwork
    args = [p.ctypes.data_as(ptr), None, None, None, None, lam.ctypes.data_as(ptr), reac.ctypes.data_as(ptr),
            info.ctypes.data_as(iptr), work.ctypes.data_as(ptr), iwork.ctypes.data_as(iptr)]
    qd_new, qdd_new = np.zeros(ng), np.zeros(ng)
    iterations, seconds, torque = [], [], []
    for k in range(n):
        t = a.t0 + k * h
        guess = np.ascontiguousarray(_guess(order, q, qd, qdd, h) if k else q)
        qd_ptr, qdd_ptr = qd_new.ctypes.data_as(ptr), qdd_new.ctypes.data_as(ptr)
        tick = time.perf_counter()
        status = fn(t, args[0], tol, guess.ctypes.data_as(ptr), qd_ptr, qdd_ptr, *args[5:])
        seconds.append(time.perf_counter() - tick)
        if status != 0:
            return {"error": f"status {status} at t = {t}", "iterations": iterations, "seconds": seconds[:-1],
                    "torque": torque}
        q, qd, qdd = guess, qd_new.copy(), qdd_new.copy()
        iterations.append(int(info[0]))
        torque.append(float(reac[index]))
    return {"error": None, "iterations": iterations, "seconds": seconds, "torque": torque}


DRIVERS = {"python-newton": python_newton, "compiled-instant": compiled_instant}
