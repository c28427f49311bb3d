"""Kinematics, inverse dynamics and statics over time.

One loop for every backend: Newton-Raphson positions warm-started from the
previous instant, then one factorization of `Phi_q` reused for qdot, qddot
and (transposed) lambda. Instants are yielded one by one so that results can
stream to a file with memory that does not grow with the run.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Iterator

import numpy as np
import scipy.linalg as sla

from symid.backends import Array, Evaluator
from symid.errors import AnalysisError
from symid.model import Analysis

EPS = np.finfo(float).eps
MAX_NEWTON = 50
# Below this reciprocal condition number (1-norm estimate from the LU
# factors) Phi_q is treated as singular: the solves would have fewer than
# ~3 correct digits left.
SINGULAR_RCOND = 1e3 * EPS


@dataclass
class Instant:
    """The state at one output instant; absent quantities are None.

    Sizes: q, qd, qdd: (ng,); lam: (nc,); reactions: as `Evaluator.reactions`.
    """

    t: float
    q: Array
    qd: Array | None = None
    qdd: Array | None = None
    lam: Array | None = None
    reactions: Array | None = None
    cond: float = float("nan")
    iterations: int = 0


def _factor(ev: Evaluator, q: Array, t: float) -> tuple[tuple[Array, Array], float]:
    """LU factors of Phi_q(q) and its 1-norm condition estimate; raise if singular."""
    jac = ev.phi_q(q, t)
    with warnings.catch_warnings():  # a singular matrix is reported below, in one line
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu = sla.lu_factor(jac, check_finite=False)
    anorm = np.linalg.norm(jac, 1)
    rcond = sla.lapack.dgecon(lu[0], anorm, norm="1")[0] if anorm > 0 else 0.0
    if not rcond > SINGULAR_RCOND:
        names = ", ".join(_dependent(ev, jac))
        cond = "inf" if rcond == 0 else f"{1 / rcond:.3g}"
        raise AnalysisError(f"Phi_q is singular (condition estimate {cond}); dependent constraints: {names}", t)
    return lu, 1.0 / rcond


def _dependent(ev: Evaluator, jac: Array) -> list[str]:
    """Constraints whose rows combine to (nearly) zero: the left null vector's support."""
    u, sv, _ = np.linalg.svd(jac)
    null = np.abs(u[:, -1])
    rows = np.flatnonzero(null > 0.05 * null.max())
    return ev.layout.constraint_names_of_rows(rows)


def newton(ev: Evaluator, q: Array, t: float, tol: float) -> tuple[Array, int]:
    """Solve Phi(q, t) = 0 from the guess q.

    Stops when max|Phi| <= tol and the last correction max|dq| <= tol, each
    floored at a few ulps of the largest coordinate (angles grow without
    bound over long runs and cannot be resolved finer than that).

    Raises:
        AnalysisError: no convergence in MAX_NEWTON iterations, or Phi_q singular.
    """
    step = np.inf
    for it in range(MAX_NEWTON + 1):
        phi = ev.phi(q, t)
        floor = 8 * EPS * max(1.0, float(np.max(np.abs(q))))
        if not np.all(np.isfinite(phi)):
            break
        if np.max(np.abs(phi)) <= max(tol, floor) and step <= max(tol, floor):
            return q, it
        if it == MAX_NEWTON:
            break
        lu, _ = _factor(ev, q, t)
        dq = sla.lu_solve(lu, -phi, check_finite=False)
        q = q + dq
        step = float(np.max(np.abs(dq)))
    worst = np.argsort(-np.abs(np.nan_to_num(phi, nan=np.inf)))[:3]
    names = ", ".join(ev.layout.constraint_names_of_rows(worst))
    raise AnalysisError(
        f"Newton did not converge in {MAX_NEWTON} iterations (max |Phi| = {np.max(np.abs(phi)):.3g}); "
        f"largest residuals in: {names}", t)


def run(ev: Evaluator, analysis: Analysis, q0: Array) -> Iterator[Instant]:
    """Solve every output instant of `analysis`, yielding them in order.

    Args:
        ev: the evaluator (its `needs` already say which reactions to compute).
        q0: initial guess at t0, size ng.

    Raises:
        AnalysisError: with `time` and `solved` set, at the first failure.
    """
    groups = analysis.output_groups()
    statics = analysis.kind == "statics"
    want_lam = not analysis.kind == "kinematics" and ("lambda" in groups or "reactions" in groups)
    want_reactions = "reactions" in groups and analysis.kind != "kinematics"
    mass = ev.mass() if want_lam and not statics else None
    times = analysis.times()
    history: list[Array] = []
    prev: Instant | None = None
    for n, t in enumerate(times):
        try:
            guess = q0 if prev is None else _predict(prev, history, t)
            q, iterations = newton(ev, guess, t, analysis.tol)
            lu, cond = _factor(ev, q, t)
            out = Instant(t=t, q=q, cond=cond, iterations=iterations)
            if statics:
                if want_lam:
                    out.lam = sla.lu_solve(lu, ev.applied(q, None, t), trans=1, check_finite=False)
            else:
                out.qd = sla.lu_solve(lu, ev.nu(q, t), check_finite=False)
                out.qdd = sla.lu_solve(lu, ev.gamma(q, out.qd, t), check_finite=False)
                if want_lam:
                    rhs = ev.applied(q, out.qd, t) - mass * out.qdd  # type: ignore[operator]
                    out.lam = sla.lu_solve(lu, rhs, trans=1, check_finite=False)
            if want_reactions and out.lam is not None:
                out.reactions = ev.reactions(q, out.lam, t)
        except AnalysisError as exc:
            exc.time, exc.solved = t, n
            raise
        history = (history + [q])[-3:]
        prev = out
        yield out


def _predict(prev: Instant, history: list[Array], t: float) -> Array:
    """Guess q(t): Taylor from the last instant's q, qdot, qddot, or, with no
    rates (statics), the polynomial through the last (equally spaced) positions."""
    h = t - prev.t
    if prev.qd is not None and prev.qdd is not None:
        return prev.q + h * prev.qd + 0.5 * h * h * prev.qdd
    if len(history) >= 3:
        return 3 * history[-1] - 3 * history[-2] + history[-3]
    if len(history) == 2:
        return 2 * history[-1] - history[-2]
    return prev.q
