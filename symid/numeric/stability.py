"""Numerical stability of the Python loop: equilibration, factorizations and
the warnings a run collects (the rank analysis: symid.numeric.redundancy).

Units. Lengths are in whatever unit the file uses, so raw `max |Phi|`,
`max |dq|` and the condition number of `Phi_q` change with it. A `Scaling`
fixed at t0 makes them unit-free: x and y columns are divided by a
characteristic length `lref` of the mechanism (a median moment arm read off
`Phi_q`), phi columns by 1, and each row by its norm in those units. Metres
and millimetres then give the same scaled matrix, the same Newton stopping
decisions and the same `cond` (docs/analysis-options.md says how `tol` reads).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from symid.model.analysis import Analysis
from symid.numeric.evaluator import Array


@functools.cache
def _sla():  # type: ignore[no-untyped-def]
    """scipy.linalg, imported on first use: a run on a compiled backend never needs it."""
    import scipy.linalg

    return scipy.linalg

EPS = float(np.finfo(float).eps)
# Below this reciprocal condition number (1-norm estimate of the equilibrated
# Phi_q) Phi_q is singular: solves would keep fewer than ~3 correct digits.
SINGULAR_RCOND = 1e3 * EPS
# Compiled loops hand over an instant whose scaled pivots spread past cond_warn / SCREEN; the C
# loop first checks its own 1-norm estimate against cond_warn / ESTIMATE_MARGIN (docs/analysis-options.md).
SCREEN, ESTIMATE_MARGIN = 1e3, 100.0
# From this many coordinates on the Python loop takes Phi_q as a sparse matrix
# (`Evaluator.phi_q_sparse`) and factors it with SuperLU: a dense one of the
# ladder of 1024 four-bars (ng 6147) is 302 MB a copy, and its LU 25 s.
SPARSE_MIN = 600
# A row belongs to a dependency when its squared projection on the left null
# space exceeds this fraction of the largest one.
NULL_SHARE = 1e-4


def _power_of_two(x: Array) -> Array:
    """Nearest powers of two: scaling by them is exact in floating point."""
    return np.exp2(np.round(np.log2(x)))


ARM_FLOOR = 1e-6  # an arm below this fraction of the largest is a point at a centre, not a length


def reference_length(arms: Array) -> float:
    """The characteristic length of a mechanism from its moment arms (rows of
    Phi_q with both kinds of entries: the ratio is a length in the file's unit).

    The median of the arms, leaving out those that vanish against the largest:
    a pin at a body's centre of mass has an arm of zero (or 1e-7 from rounding a
    derived centre), which says nothing of the mechanism's size; as the median
    it made a well-conditioned Phi_q look singular once scaled. 0 when no arm is
    left (the caller falls back to the coordinates).
    """
    arms = np.asarray(arms, dtype=float)
    arms = arms[np.isfinite(arms)]
    if not arms.size:
        return 0.0
    return float(np.median(arms[arms >= ARM_FLOOR * arms.max()]))


@dataclass(frozen=True)
class Scaling:
    """Row and column scales of Phi_q, fixed for a run.

    Attributes:
        lref: characteristic length (units of the file's lengths).
        col: size ng, lref for x and y, 1 for phi: q / col is unit-free.
        row: size nc, the norm of each row of Phi_q diag(col): Phi / row is unit-free.
        dc, dr: the nearest powers of two of col and 1 / row (exact scalings).
    """

    lref: float
    col: Array
    row: Array
    dc: Array = field(repr=False)
    dr: Array = field(repr=False)
    inv_col: Array = field(repr=False)
    inv_row: Array = field(repr=False)

    @classmethod
    def of(cls, jac: Array, q: Array) -> "Scaling":
        """Scales from Phi_q (nc, ng; dense, or scipy sparse) at configuration q (ng,)."""
        if is_sparse(jac):
            from symid.numeric.sparse_scaling import scaling_of_entries

            coo = jac.tocoo()
            return scaling_of_entries(coo.row, coo.col, coo.data, q, jac.shape[0])
        ng = jac.shape[1]
        rot = np.zeros(ng, dtype=bool)
        rot[2::3] = True
        lin_part = np.abs(jac[:, ~rot]).max(axis=1, initial=0.0)
        rot_part = np.abs(jac[:, rot]).max(axis=1, initial=0.0)
        mixed = (lin_part > 0) & (rot_part > 0)
        # rows with both kinds of entries (revolutes, slots, distances): the
        # ratio is a moment arm, a length in the file's unit
        lref = reference_length(rot_part[mixed] / lin_part[mixed])
        if not lref > 0:
            lref = float(np.max(np.abs(q[~rot]), initial=0.0))
        if not lref > 0 or not np.isfinite(lref):
            lref = 1.0
        col = np.where(rot, 1.0, lref)
        row = np.abs(jac * col[None, :]).max(axis=1, initial=0.0)
        row = np.where((row > 0) & np.isfinite(row), row, 1.0)
        return cls(lref, col, row, _power_of_two(col), 1.0 / _power_of_two(row), 1.0 / col, 1.0 / row)

    def residual(self, phi: Array) -> float:
        """max_i |Phi_i| / row_i (NaN when Phi is not finite)."""
        return float(np.abs(phi * self.inv_row).max(initial=0.0)) if phi.size else 0.0

    def size(self, dq: Array) -> float:
        """max_j |dq_j| / col_j."""
        return float(np.abs(dq * self.inv_col).max(initial=0.0)) if dq.size else 0.0

    def merit(self, phi: Array) -> float:
        """The 2-norm of the scaled residual (the damped step's merit)."""
        v = phi * self.inv_row
        return math.sqrt(float(v @ v))


def is_sparse(jac: object) -> bool:
    """Whether jac is a scipy sparse matrix (scipy imported only if one could be)."""
    return not isinstance(jac, np.ndarray) and hasattr(jac, "tocsc")


def _getrf(*args, **kwargs):  # type: ignore[no-untyped-def]
    return _sla().lapack.dgetrf(*args, **kwargs)


def _getrs(*args, **kwargs):  # type: ignore[no-untyped-def]
    return _sla().lapack.dgetrs(*args, **kwargs)


def _gecon(*args, **kwargs):  # type: ignore[no-untyped-def]
    return _sla().lapack.dgecon(*args, **kwargs)


class Factor:
    """A factorization of Phi_q (nc, ng) at one configuration, equilibrated.

    Square: LU of D_r Phi_q D_c (LAPACK directly: the scipy wrappers cost more
    than a small factorization). More rows than columns (redundant
    constraints): thin QR of Phi_q D_c, rows unscaled so that `solve_t` gives
    the minimum-norm multipliers of the file's own rows (sparse: the same
    solves through `symid.numeric.sparse_rank.LeastSquares`). D_r, D_c are the
    scaling's powers of two, so equilibrating adds no rounding.

    Attributes:
        rcond: reciprocal 1-norm condition estimate of the equilibrated matrix.
    """

    def __init__(self, jac: Array, scaling: Scaling) -> None:
        nc, ng = jac.shape
        self.dc = scaling.dc
        self.square = nc == ng
        self.splu = self.lsq = None
        self.jac = jac
        if is_sparse(jac) and not self.square:  # redundant rows, large: the thin QR's solves, sparse
            self._sparse_lstsq(jac)
        elif is_sparse(jac):
            self.dr = scaling.dr
            self._sparse_lu(jac, scaling)
        elif self.square:
            self.dr = scaling.dr
            a = jac * self.dr[:, None] * self.dc
            anorm = float(np.abs(a).sum(axis=0).max(initial=0.0))
            self.lu, self.piv, info = _getrf(a)
            if info != 0 or not anorm > 0 or not np.isfinite(anorm):  # an exactly zero pivot, or NaN
                self.rcond = 0.0
            else:
                self.rcond = float(_gecon(self.lu, anorm, norm="1")[0])
        else:
            a = jac * self.dc
            self.q, self.r = np.linalg.qr(a)
            self.rcond = float(_sla().lapack.dtrcon(self.r, norm="1")[0]) if ng else 1.0
        if not np.isfinite(self.rcond):
            self.rcond = 0.0

    def _sparse_lu(self, jac: object, scaling: Scaling) -> None:
        """SuperLU of D_r Phi_q D_c and LAPACK's rcond estimate, sparse: the
        1-norm of the inverse by Higham's estimator (scipy's onenormest, what
        gecon estimates too) on solves with the factors."""
        from scipy import sparse
        from scipy.sparse.linalg import LinearOperator, onenormest, splu

        a = (sparse.diags(self.dr) @ jac @ sparse.diags(self.dc)).tocsc()  # type: ignore[operator]
        anorm = float(np.asarray(abs(a).sum(axis=0)).max(initial=0.0)) if a.nnz else 0.0
        self.rcond = 0.0
        if not anorm > 0 or not np.isfinite(anorm):
            return
        try:
            lu = splu(a)
        except RuntimeError:  # "Factor is exactly singular"
            return
        n = a.shape[0]
        inverse = LinearOperator((n, n), matvec=lu.solve, rmatvec=lambda b: lu.solve(b, trans="T"),
                                 dtype=float)
        with np.errstate(all="ignore"):
            inorm = float(onenormest(inverse)) if n > 1 else float(abs(lu.solve(np.ones(1)))[0])
        self.splu = lu
        self.rcond = 1.0 / (anorm * inorm) if inorm > 0 and np.isfinite(inorm) else 0.0

    def _sparse_lstsq(self, jac: object) -> None:
        from scipy import sparse

        from symid.numeric.sparse_rank import LeastSquares

        try:
            self.lsq = LeastSquares(jac @ sparse.diags(self.dc))  # type: ignore[operator]
            self.rcond = self.lsq.rcond
        except RuntimeError:  # "Factor is exactly singular": column-rank deficient
            self.rcond = 0.0

    @property
    def cond(self) -> float:
        return np.inf if self.rcond == 0 else 1.0 / self.rcond

    def solve(self, b: Array) -> Array:
        """x with Phi_q x = b (size nc -> ng; least squares when nc > ng)."""
        if self.splu is not None:
            return self.dc * self.splu.solve(self.dr * b)
        if self.lsq is not None:
            return self.dc * self.lsq.solve(b)
        if self.square:
            return self.dc * _getrs(self.lu, self.piv, self.dr * b)[0]
        return self.dc * _sla().solve_triangular(self.r, self.q.T @ b, check_finite=False)

    def solve_t(self, b: Array) -> Array:
        """lambda with Phi_q^T lambda = b (size ng -> nc; minimum norm when nc > ng).

        One step of iterative refinement where the residual asks for it
        (`refine_wanted`): the LU of Phi_q solves the transposed system
        backward stably in the norm of the whole b, so on a mechanism of mixed
        scales (a 2 g part on a boom of 1e5 N) a light body's multipliers carry
        the heavy ones' rounding, 1e-9 of its own loads. The residual
        b - Phi_q^T lambda, computed in working precision, is exact to the
        rounding of each row's own terms, and its correction through the same
        factors brings every multiplier to that."""
        lam = self._solve_t(b)
        jt = self.jac.T
        r = b - jt @ lam
        if not refine_wanted(r, abs(jt) @ np.abs(lam) + np.abs(b), float(self.dc[0]) if len(self.dc) else 1.0):
            return lam
        return lam + self._solve_t(r)

    def _solve_t(self, b: Array) -> Array:
        if self.splu is not None:
            return self.dr * self.splu.solve(self.dc * b, trans="T")
        if self.lsq is not None:
            return self.lsq.solve_t(self.dc * b)
        if self.square:
            return self.dr * _getrs(self.lu, self.piv, self.dc * b, trans=1)[0]
        return self.q @ _sla().solve_triangular(self.r, self.dc * b, trans="T", check_finite=False)


# A transposed solve (the multipliers) is refined, one step of iterative
# refinement through the same factors, where its residual r = b - Phi_q^T lam
# is past REFINE_BERR roundings of a body's own terms in some row: |r_i| >
# REFINE_BERR eps s_i, s = |Phi_q^T| |lam| + |b| (a componentwise backward
# error, as LAPACK's dgerfs measures it) with a body's x and y rows sharing
# the larger of their two and its angle's row at least that force times the
# mechanism's length (Scaling.lref): a row whose terms all vanish (a
# platform with no horizontal load, a lamp's angle held with no torque)
# would otherwise ask for a correction of its rounding noise. Where the first
# solve is at rounding (the bundled examples: <= 2 eps at 95 % of the instants,
# 50 at the worst) no correction is solved; a 2 g part on a 1 t boom (~1e6)
# and Andrews' mechanism (~400) are refined. The Python loop's rule (friction
# and the sensitivities too: they solve through Factor.solve_t); generated
# code gates on the masses' spread (REFINE_SPREAD, once a call): its outputs
# have no length scale for the angle rows.
REFINE_BERR = 16.0


def refine_wanted(r: Array, scale: Array, lref: float = 1.0) -> bool:
    """Whether a residual r (ng,) or (ng, m) of Phi_q^T lam = b is past
    REFINE_BERR roundings of scale = |Phi_q^T| |lam| + |b| (same shape),
    a body's x and y rows taking the larger of their two scales, its angle
    row at least that times lref."""
    s = np.array(scale, dtype=float).reshape(-1, 3, *np.shape(scale)[1:])
    s[:, :2] = np.max(s[:, :2], axis=1, keepdims=True)
    s[:, 2] = np.maximum(s[:, 2], lref * s[:, 0])
    return bool(np.any(np.abs(r) > (REFINE_BERR * EPS) * s.reshape(np.shape(scale))))


SHOWN_INTERVALS = 3


@dataclass
class _Span:
    """Where one kind of warning applied: the first SHOWN_INTERVALS runs of
    consecutive instants, how many more, the count and the worst value."""

    intervals: list[list[float]] = field(default_factory=list)  # [first t, last t, last index]
    more: int = 0
    count: int = 0
    worst: float = 0.0
    worst_t: float = 0.0
    last: int = -2  # index of the latest instant marked

    def add(self, t: float, value: float, index: int) -> None:
        self.count += 1
        if value > self.worst or self.count == 1:
            self.worst, self.worst_t = value, t
        if self.intervals and self.intervals[-1][2] == index - 1:
            self.intervals[-1][1:] = [t, index]
        elif len(self.intervals) < SHOWN_INTERVALS:
            self.intervals.append([t, t, index])
        elif self.last != index - 1:
            self.more += 1
        self.last = index

    def where(self) -> str:
        text = " and ".join(f"[{a:.9g}, {b:.9g}]" for a, b, _ in self.intervals)
        return f"t in {text}" + (f" and {self.more} more intervals" if self.more else "")


@dataclass
class Notes:
    """Warnings of one run, one per kind, with the spans of times it covers.

    Memory is constant: a few intervals per kind, never a list of instants.
    """

    analysis: Analysis
    spans: dict[str, _Span] = field(default_factory=dict)
    fixed: list[str] = field(default_factory=list)

    def mark(self, kind: str, t: float, value: float, index: int) -> None:
        self.spans.setdefault(kind, _Span()).add(t, value, index)

    def cond(self, t: float, cond: float, index: int) -> None:
        if cond > self.analysis.cond_threshold:
            self.mark("cond", t, cond, index)

    def worst_cond(self) -> float:
        """The largest condition estimate above cond_warn in the run (0.0: none, no warning)."""
        return float(self.spans["cond"].worst) if "cond" in self.spans else 0.0

    def lines(self) -> list[str]:
        """The warnings, one line each (without the `symid: warning: ` prefix)."""
        out = list(self.fixed)
        span = self.spans.get("cond")
        if span is not None:
            digits = min(16, round(2 * np.log10(span.worst))) if np.isfinite(span.worst) else 16
            out.append(f"Phi_q is ill-conditioned: cond above cond_warn = {self.analysis.cond_threshold:g} "
                       f"at {span.count} instants, {span.where()}, worst {span.worst:.3g} at "
                       f"t = {span.worst_t:.9g}: the mechanism is near a singular position; accelerations, "
                       f"multipliers and torques there may have lost up to {digits} of their 16 digits "
                       f"(positions and velocities about half as many)")
        span = self.spans.get("jump")
        if span is not None:
            out.append(f"assembly mode jump at {span.count} instants, {span.where()} (allowed by "
                       f"assembly_jump = \"warn\"): the solution switched to another assembly mode; the "
                       f"largest jump moved q by {span.worst:.3g} (scaled) at t = {span.worst_t:.9g}")
        return out


# -- what each backend supports -------------------------------------------------

FEATURES = {  # feature -> (the [analysis] key that asks for it, what it is)
    "cond": ("outputs", "the cond column"),
    "cond_warn": ("cond_warn", "the condition-number warning"),
    "min_norm": ("redundant", "redundant constraints (minimum-norm multipliers)"),
    "assembly_jump": ("assembly_jump", "assembly-mode jump reports (assembly_jump = \"warn\")"),
}


def requested(analysis: Analysis) -> list[str]:
    """The stability features an analysis asks for beyond the defaults."""
    out = []
    if "cond" in analysis.extra_outputs():
        out.append("cond")
    if analysis.cond_warn is not None:
        out.append("cond_warn")
    if analysis.redundant != "error":
        out.append("min_norm")
    if analysis.assembly_jump != "error":
        out.append("assembly_jump")
    return out


def jacobian(ev, q, t):  # type: ignore[no-untyped-def]
    """Phi_q(q, t) as the Python loop takes it (ev: an evaluator): dense below
    SPARSE_MIN coordinates, a scipy CSC matrix from there on (nothing nc x ng).
    An evaluator loaded for a planned run has no layout: dense, as the run
    that made the plan (symid.tools.plan) took it below SPARSE_MIN."""
    if ev.layout is not None and ev.layout.ng >= SPARSE_MIN:
        return ev.phi_q_sparse(q, t)
    return ev.phi_q(q, t)
