"""`symid check`: counts, rank and conditioning at the assembled initial configuration."""

from __future__ import annotations

from dataclasses import dataclass

from symid.errors import AnalysisError
from symid.text import plural
from symid.numeric.solve import jacobian, newton
from symid.numeric.redundancy import assemble_lstsq, rank_of
from symid.numeric.stability import Factor, Scaling


@dataclass(frozen=True)
class CheckReport:
    """What `symid check` found.

    Attributes:
        rank: numerical rank of Phi_q at q(t0) (SVD of the equilibrated
            matrix, tolerance max(nc, ng) * eps * s_max).
        cond: 2-norm condition number of the equilibrated Phi_q (inf when rank < ng).
        cond_estimate: the 1-norm estimate the `cond` column reports (inf when singular).
        iterations: Newton iterations to assemble (0: assembled by least squares).
        dependent: constraints whose rows are dependent (empty at full row rank).
        cond_warn: the run's warning threshold.
    """

    name: str
    ng: int
    nc: int
    rank: int
    cond: float
    iterations: int
    dependent: tuple[str, ...]
    cond_estimate: float = float("nan")
    cond_warn: float = float("inf")

    @property
    def singular(self) -> bool:
        """The kinematics is not determined: fewer independent rows than coordinates."""
        return self.rank < self.ng

    def text(self) -> str:
        how = (f"in {plural(self.iterations, 'Newton iteration')}" if self.iterations
               else "by least squares (Phi_q is rank-deficient)")
        lines = [f"mechanism {self.name}: ng = {self.ng}, nc = {self.nc}",
                 f"assembled at t0 {how}",
                 f"rank of Phi_q = {self.rank} of {min(self.ng, self.nc)}, condition number = {self.cond:.6g} "
                 f"(equilibrated; the cond column's estimate: {self.cond_estimate:.3g})"]
        if self.dependent and not self.singular:
            lines.append("redundant constraints (their multipliers and reactions are not unique; "
                         "solve with [analysis] redundant = \"min_norm\"): " + ", ".join(self.dependent))
        elif self.dependent:
            lines.append("dependent constraints: " + ", ".join(self.dependent))
        if self.cond_estimate > self.cond_warn:
            lines.append(f"the condition number is above cond_warn = {self.cond_warn:g}: "
                         f"q0 is near a singular position")
        return "\n".join(lines)


def check(study) -> CheckReport:  # type: ignore[no-untyped-def]
    """Assemble the mechanism at t0 from q0 and analyse Phi_q there.

    A rank-deficient Phi_q is assembled by least squares and reported (the
    caller decides the exit status from `CheckReport.singular`).

    Raises:
        AnalysisError: the mechanism cannot be assembled from q0.
    """
    ev = study.evaluator
    analysis = study.analysis
    t0 = analysis.t0
    try:
        q, iterations = newton(ev, study.q0(), t0, analysis.tol)
    except AnalysisError:
        q, _ = assemble_lstsq(ev, study.q0(), t0, analysis.tol)
        iterations = 0
    jac = jacobian(ev, q, t0)  # sparse from SPARSE_MIN coordinates on
    scaling = Scaling.of(jac, q)
    rank = rank_of(jac, scaling, study.layout)
    layout = study.layout
    return CheckReport(study.mechanism.name, layout.ng, layout.nc, rank.rank, rank.cond, iterations,
                       rank.dependent, Factor(jac, scaling).cond, analysis.cond_threshold)
