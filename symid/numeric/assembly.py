"""Assembly at t0 for large mechanisms: Newton on Phi(q, t0) = 0 with a
sparse LU, so that setup holds nothing nc x ng (a dense Phi_q of the ladder
of 1024 is 302 MB).

Setup needs this configuration only as the sample that guides the pivot
choice of the generated code (`symid.codegen.model`); the run's own
assembly, with its diagnostics, is `symid.numeric.solve.newton`.
"""

from __future__ import annotations

import numpy as np

from symid.errors import AnalysisError
from symid.numeric.newton import RULE
from symid.numeric.reference import ReferenceEvaluator

Array = np.ndarray


def jacobian(ev: ReferenceEvaluator, q: Array, t: float):  # type: ignore[no-untyped-def]
    """Phi_q(q, t) as a scipy CSC matrix (nc, ng)."""
    from scipy import sparse as sps

    r, c, v = ev.phi_q_entries(q, t)
    return sps.csc_matrix((v, (r, c)), shape=(ev.layout.nc, ev.layout.ng))


def assemble(ev: ReferenceEvaluator, q: Array, t: float, tol: float) -> Array:
    """q near the guess with Phi(q, t) = 0, by damped Newton with a sparse LU.

    Converged: max |Phi| and the last correction within tol, floored at the
    rounding of the largest coordinate (the rule's floor).

    Raises:
        AnalysisError: Phi not finite, Phi_q singular or not square, no
            convergence in RULE.max_iterations.
    """
    from scipy.sparse.linalg import splu

    if ev.layout.nc != ev.layout.ng:
        raise AnalysisError("sparse assembly needs a square Phi_q", t)
    q = np.array(q, dtype=float)
    phi = ev.phi(q, t)
    for _ in range(RULE.max_iterations):
        res = float(np.abs(phi).max(initial=0.0))
        if not np.isfinite(res):
            raise AnalysisError("Phi is not finite at the assembly guess", t)
        lim = max(tol, RULE.floor(float(np.abs(q).max(initial=0.0))))
        try:
            dq = splu(jacobian(ev, q, t)).solve(-phi)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise AnalysisError(f"Phi_q is singular at the assembly guess ({exc})", t) from None
        step = float(np.abs(dq).max(initial=0.0))
        if res <= lim and step <= lim:
            return q
        merit, alpha = float(phi @ phi), 1.0
        while True:  # halve until |Phi| decreases (full steps near the solution)
            trial = q + alpha * dq
            phi_trial = ev.phi(trial, t)
            if float(phi_trial @ phi_trial) <= merit or res <= RULE.noise * lim or alpha < RULE.min_damping:
                break
            alpha *= 0.5
        q, phi = trial, phi_trial
    raise AnalysisError(f"assembly did not converge in {RULE.max_iterations} iterations", t)

