"""`symid check`: counts, rank and conditioning at the assembled initial configuration."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symid.solve import newton


@dataclass(frozen=True)
class CheckReport:
    """What `symid check` found.

    Attributes:
        rank: numerical rank of Phi_q at q(t0) (SVD, tolerance ng * eps * s_max).
        cond: 2-norm condition number s_max / s_min (inf when singular).
        dependent: constraints whose rows are dependent (empty at full rank).
    """

    name: str
    ng: int
    nc: int
    rank: int
    cond: float
    iterations: int
    dependent: tuple[str, ...]

    def text(self) -> str:
        lines = [f"mechanism {self.name}: ng = {self.ng}, nc = {self.nc}",
                 f"assembled at t0 in {self.iterations} Newton iterations",
                 f"rank of Phi_q = {self.rank} of {min(self.ng, self.nc)}, condition number = {self.cond:.6g}"]
        if self.dependent:
            lines.append("dependent constraints: " + ", ".join(self.dependent))
        return "\n".join(lines)


def check(study) -> CheckReport:  # type: ignore[no-untyped-def]
    """Assemble the mechanism at t0 from q0 and analyse Phi_q there.

    Raises:
        AnalysisError: the mechanism cannot be assembled from q0.
    """
    ev = study.evaluator
    t0 = study.analysis.t0
    q, iterations = newton(ev, study.q0(), t0, study.analysis.tol)
    jac = ev.phi_q(q, t0)
    u, sv, _ = np.linalg.svd(jac)
    tol = max(jac.shape) * np.finfo(float).eps * (sv[0] if sv.size else 0.0)
    rank = int(np.sum(sv > tol))
    cond = float(sv[0] / sv[-1]) if sv.size and sv[-1] > 0 else float("inf")
    dependent: list[str] = []
    if rank < len(sv):
        null = np.abs(u[:, rank:]).max(axis=1)
        dependent = study.layout.constraint_names_of_rows(np.flatnonzero(null > 0.05 * null.max()))
    layout = study.layout
    return CheckReport(study.mechanism.name, layout.ng, layout.nc, rank, cond, iterations, tuple(dependent))
