"""What Newton's tolerance and the predictor's order cost and buy.

symid's Python loops predict each instant's q with a 2nd-order Taylor step
from the previous one; the generated C trajectory goes to h^5 and takes the
first correction with the previous instant's factors. Here the benchmark
drives Newton itself so the order can vary: order 0 starts from the previous
q, 1 adds h qdot, 2 adds h^2/2 qddot, 5 adds the h^3 to h^5 terms from the
cubic through the last four accelerations (the C trajectory's predictor;
every correction here factors Phi_q anew). Two drivers over the same C
backend of one mechanism:

- `python_newton`: the Evaluator protocol (phi, phi_q, ...) with SciPy's LU,
  Newton as in `symid.numeric.solve` (stop when max |Phi| and the last max |dq| are
  both <= max(tol, 8 eps max(1, max |q|))).
- `compiled_loop`: the generated `<name>_instant` (Newton, qdot, qddot,
  lambda, reactions in C) called in a C loop (`predictor_loop.c`, linked
  with the generated solver, gcc -O2) that makes the guess of the chosen
  order; timed inside C.

Both return the Newton iterations per instant, the time per instant and the
motor torque, from which the caller computes the error.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from symid import api

EPS = float(np.finfo(float).eps)


def motor_reaction_index(study: api.Study, column: str = "motor.T_j") -> int:
    """Index of a reaction column within `Evaluator.reactions`' vector."""
    cols = study.columns()
    first = next(k for k, c in enumerate(cols) if c.endswith(".Fx_i"))
    return cols.index(column) - first


def _guess(order: int, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, h: float,
           before: list[np.ndarray]) -> np.ndarray:
    """The predictor; `before` holds the accelerations before qdd, latest first."""
    if order == 0:
        return q.copy()
    if order == 1:
        return q + h * qd
    if order == 2 or len(before) < 3:
        return q + h * qd + 0.5 * h * h * qdd
    m1, m2, m3 = before[:3]
    return q + h * (qd + h * (323.0 * qdd - 264.0 * m1 + 159.0 * m2 - 38.0 * m3) / 360.0)


def python_newton(study: api.Study, order: int, tol: float, n: int) -> dict[str, Any]:
    """n instants of the study's grid with a predictor of the given order."""
    import scipy.linalg as sla  # here: every harness process imports this module (the registry), few call this

    ev, a = study.evaluator, study.analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    index = motor_reaction_index(study)
    mass = ev.mass()
    q, qd, qdd = study.q0(), np.zeros(study.layout.ng), np.zeros(study.layout.ng)
    iterations, seconds, torque = [], [], []
    before: list[np.ndarray] = []
    for k in range(n):
        tick = time.perf_counter()
        t = a.t0 + k * h
        q = _guess(order, q, qd, qdd, h, before) if k else q
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
        before = [qdd, *before[:2]] if k else []
        qd = sla.lu_solve(lu, ev.nu(q, t), check_finite=False)
        qdd = sla.lu_solve(lu, ev.gamma(q, qd, t), check_finite=False)
        lam = sla.lu_solve(lu, ev.applied(q, qd, t) - mass * qdd, trans=1, check_finite=False)
        torque.append(float(ev.reactions(q, lam, t)[index]))
        seconds.append(time.perf_counter() - tick)
        iterations.append(it)
    return {"error": None, "iterations": iterations, "seconds": seconds, "torque": torque}


LOOP_SOURCE = Path(__file__).with_name("predictor_loop.c")


def _compiled_loop(study: api.Study) -> ctypes.CDLL:
    """symid's generated solver of this study linked with predictor_loop.c (built once per study)."""
    from symid.backends.c_backend import build
    from symid.codegen.model import options_for

    cached = getattr(study, "_predictor_loop", None)
    if cached is not None:
        return cached  # type: ignore[no-any-return]
    name = study.mechanism.name
    folder = build(study.layout, options_for(study.mechanism))
    out = Path(tempfile.mkdtemp(prefix="symid-bench-predictor-")) / "loop.so"
    cmd = ["gcc", "-O2", "-fPIC", "-shared", f"-DP={name}", f"-DPU={name.upper()}", f"-I{folder}",
           str(folder / f"{name}_solver.c"), str(LOOP_SOURCE), "-o", str(out), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"compiling the predictor loop failed:\n{done.stderr[-2000:]}")
    lib = ctypes.CDLL(str(out))
    shutil.rmtree(out.parent, ignore_errors=True)  # mapped: the file is no longer needed
    dbl, ptr, iptr = ctypes.c_double, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
    lib.predictor_loop.argtypes = [dbl, dbl, ctypes.c_long, ctypes.c_int, dbl, ptr, ptr, ctypes.c_int, ptr, iptr,
                                   ptr]
    lib.predictor_loop.restype = ctypes.c_long
    object.__setattr__(study, "_predictor_loop", lib)
    return lib


def compiled_loop(study: api.Study, order: int, tol: float, n: int) -> dict[str, Any]:
    """The same with the C backend's `<name>_instant` in a C loop: the time is
    the loop's own (clock_gettime) divided by the instants, in every entry."""
    lib = _compiled_loop(study)
    a = study.analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    ptr, iptr = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
    p = np.ascontiguousarray(study.evaluator.p, dtype=float)
    q0 = np.ascontiguousarray(study.q0())
    torque, its, ns = np.zeros(n), np.zeros(n, dtype=np.intc), np.zeros(1)
    solved = lib.predictor_loop(a.t0, h, n, order, tol, p.ctypes.data_as(ptr), q0.ctypes.data_as(ptr),
                                motor_reaction_index(study), torque.ctypes.data_as(ptr), its.ctypes.data_as(iptr),
                                ns.ctypes.data_as(ptr))
    per = float(ns[0]) * 1e-9 / max(solved, 1)
    return {"error": None if solved == n else f"the compiled instant failed at instant {solved}",
            "iterations": its[:solved].tolist(), "seconds": [per] * solved, "torque": torque[:solved].tolist()}


DRIVERS = {"python-newton": python_newton, "compiled-loop": compiled_loop}
