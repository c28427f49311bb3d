"""The CasADi baseline of a design study: the slider-crank's instant as one
CasADi Function of (guess, t, [L_rod, n]), mapped over K variants with
`Function.map(K, "thread", 2)` and called from Python once per instant, the
way a CasADi user would run the issue-14 grid (rod length x crank speed).

The Function is the one of `benchmarks.casadi_baselines.CasadiWhole` (Newton
by `rootfinder`, QR solves, the reactions' formula) with the rod length and
the crank speed as inputs instead of numbers; the figure kept per variant is
the motor's peak |torque| (the sweep's `motor.effort_peak`).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from benchmarks.baselines import MAX_NEWTON, _reaction_slots, _symbolic_reactions, symbolic_applied, symbolic_phi
from benchmarks.systems import (A_S, B_S, F_GAS, G, GROUND, L1, M1, M2, M3, AngleDriver, Body, PointForce, Revolute,
                                System, Translational)


def slider_crank(l_rod: Any, n: Any) -> System:
    """`systems.slider_crank` with the rod length and crank speed (rev/s) as
    values of any kind (numbers or CasADi symbols)."""
    omega = 2 * math.pi * n
    bodies = [Body(M1, M1 * L1 ** 2 / 12, (L1 / 2, 0.0, 0.0)),
              Body(M2, M2 * l_rod ** 2 / 12, (L1 + l_rod / 2, 0.0, 0.0)),
              Body(M3, M3 * (A_S ** 2 + B_S ** 2) / 12, (L1 + l_rod, 0.0, 0.0))]
    joints = [Revolute(GROUND, 0, (0.0, 0.0), (-L1 / 2, 0.0)),
              Revolute(0, 1, (L1 / 2, 0.0), (-l_rod / 2, 0.0)),
              Revolute(1, 2, (l_rod / 2, 0.0), (0.0, 0.0)),
              Translational(GROUND, 2, (0.0, 0.0), (1.0, 0.0), (0.0, 0.0), 0.0),
              AngleDriver(GROUND, 0, lambda t, m: omega * t, lambda t: omega, lambda t: 0.0)]
    forces = [PointForce(2, (0.0, 0.0), lambda t, m: (-F_GAS * m.sin(omega * t), 0.0 * t))]
    return System("slider_crank", bodies, joints, forces, (0.0, -G), motor=4)  # type: ignore[arg-type]


def instant_function(tol: float = 1e-12) -> tuple[Any, int]:
    """The Function (guess[9], t, P[2] = (L_rod, n)) -> (q, qd, qdd, lam, reac)
    and the motor torque's index in reac."""
    import casadi as ca

    pl, pn = ca.SX.sym("L_rod"), ca.SX.sym("n")
    s = slider_crank(pl, pn)
    ng, nc = s.ng, s.nc
    q, qd, t, lam = ca.SX.sym("q", ng), ca.SX.sym("qd", ng), ca.SX.sym("t"), ca.SX.sym("lam", nc)
    par = ca.vertcat(pl, pn)
    phi = ca.vertcat(*symbolic_phi(s, q, t, ca))
    jac = ca.jacobian(phi, q)
    phi_t = ca.jacobian(phi, t)
    jqd = ca.mtimes(jac, qd)
    gamma = -ca.mtimes(ca.jacobian(jqd, q), qd) - 2 * ca.jacobian(jqd, t) - ca.jacobian(phi_t, t)
    tp = ca.vertcat(t, par)
    f_phi = ca.Function("phi", [q, tp], [phi])
    newton = ca.rootfinder("newton", "fast_newton", f_phi, {"abstol": tol, "abstolStep": tol, "max_iter": MAX_NEWTON})
    f_jac = ca.Function("phi_q", [q, tp], [jac])
    f_nu = ca.Function("nu", [q, tp], [-phi_t])
    f_gamma = ca.Function("gamma", [q, qd, tp], [gamma])
    f_applied = ca.Function("applied", [q, tp], [ca.vertcat(*symbolic_applied(s, q, t, ca))])
    f_reac = ca.Function("reac", [q, lam, tp], [ca.vertcat(*_symbolic_reactions(s, q, jac, lam, ca))])
    f_mass = ca.Function("mass", [par], [ca.vertcat(*[v for b in s.bodies for v in (b.mass, b.mass, b.inertia)])])
    guess, tm, pm = ca.MX.sym("guess", ng), ca.MX.sym("t"), ca.MX.sym("p", 2)
    tpm = ca.vertcat(tm, pm)
    qs = newton(guess, tpm)
    jm = f_jac(qs, tpm)
    solver = ca.Linsol("lin", "qr", jac.sparsity())
    qdm = solver.solve(jm, f_nu(qs, tpm))
    qddm = solver.solve(jm, f_gamma(qs, qdm, tpm))
    lamm = solver.solve(jm, f_applied(qs, tpm) - f_mass(pm) * qddm, True)
    outs = [ca.densify(v) for v in (qs, qdm, qddm, lamm, f_reac(qs, lamm, tpm))]
    fn = ca.Function("slider_crank_study", [guess, tm, pm], outs, ["guess", "t", "p"],
                     ["q", "qd", "qdd", "lam", "reac"])
    return fn, _reaction_slots(s)[1]


def run_mapped(params: np.ndarray, steps: int, t1: float = 0.2, threads: int = 2,
               tol: float = 1e-12) -> dict[str, Any]:
    """K variants (params: (K, 2) rod length, crank speed) x `steps` instants
    on [0, t1] (the example file's grid, as the sweep solves it), one mapped
    call per instant (the predictor of `CasadiWhole.run`, vectorized over
    variants in NumPy).

    Returns seconds (the instants' loop), per-variant motor peak |torque|,
    and us per instant (seconds / (K steps))."""
    fn, motor = instant_function(tol)
    k = len(params)
    mapped = fn.map(k, "thread", threads)
    l_rod = params[:, 0]
    ts = np.linspace(0.0, t1, steps)
    h = ts[1] - ts[0] if steps > 1 else 0.0
    q = np.zeros((9, k))
    q[0], q[3], q[6] = L1 / 2, L1 + l_rod / 2, L1 + l_rod
    qd, qdd = np.zeros((9, k)), np.zeros((9, k))
    peak = np.zeros(k)
    p = params.T.copy()
    tick = time.perf_counter()
    for j in range(steps):
        guess = q + h * qd + 0.5 * h * h * qdd if j else q
        res = mapped(guess, ts[j], p)
        q, qd, qdd = (np.asarray(r) for r in res[:3])
        peak = np.maximum(peak, np.abs(np.asarray(res[4])[motor]))
    seconds = time.perf_counter() - tick
    return {"variants": k, "steps": steps, "threads": threads, "seconds": seconds,
            "us_per_instant": 1e6 * seconds / (k * steps), "motor_peak": peak}
