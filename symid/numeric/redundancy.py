"""Rank analysis of Phi_q and the redundant-constraint reports: which rows are
dependent, which driver is one too many, and a least-squares assembly that
reaches a configuration even where Phi_q is rank-deficient (`symid check`,
the redundancy errors, the minimum-norm warning)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from symid.errors import AnalysisError, InputError
from symid.numeric.evaluator import Array, Evaluator
from symid.numeric.newton import RULE
from symid.numeric.stability import EPS, NULL_SHARE, Scaling, is_sparse, jacobian

if TYPE_CHECKING:
    from symid.model.mechanism import Mechanism
    from symid.symbolic.assemble import Layout


@dataclass(frozen=True)
class Rank:
    """Rank of Phi_q (SVD of the equilibrated matrix) and the rows in dependencies.

    Attributes:
        rank: numerical rank (singular values above max(nc, ng) eps s_max).
        cond: 2-norm condition number of the equilibrated matrix (inf if rank < ng).
        dependent: constraints with a row in the left null space (file order):
            their multipliers are not unique.
    """

    rank: int
    cond: float
    dependent: tuple[str, ...]


def rank_of(jac: Array, scaling: Scaling, layout: Layout, singular: bool = False) -> Rank:
    """The rank analysis of Phi_q (nc, ng); cost one SVD. `singular`: the caller's
    factorization found it singular, so the smallest singular value counts as null
    even when just above this rank threshold (else no constraint would be named).
    A sparse Phi_q (large mechanisms) is analysed with nothing nc x ng
    (`symid.numeric.sparse_rank`): the same rank, names and condition number."""
    from symid.numeric import sparse_rank

    if is_sparse(jac):  # the Python loop's sparse Phi_q (large mechanisms)
        full = None if singular else _full_rank_sparse(jac, scaling)
        if full is not None:
            return full
        from scipy.sparse import diags

        equilibrated = diags(1.0 / scaling.row) @ jac @ diags(scaling.col)  # type: ignore[operator]
        found = sparse_rank.analyse(equilibrated, singular)
    else:
        found = sparse_rank.dense(jac / scaling.row[:, None] * scaling.col[None, :], singular)
    share = found.share
    rows = (np.flatnonzero(share > NULL_SHARE * share.max()) if share.size and share.max() > 0
            else np.zeros(0, dtype=int))
    dependent = layout.constraint_names_of_rows(rows)
    order = [c.name for c in layout.mechanism.constraints]
    return Rank(found.rank, found.cond, tuple(sorted(dependent, key=order.index)))


def _full_rank_sparse(jac: object, scaling: Scaling) -> Rank | None:
    """`rank_of` of a square sparse Phi_q that SuperLU finds regular, without
    anything nc x ng: the extreme singular values of the equilibrated matrix by
    Lanczos (ARPACK), s_max on it and 1 / s_min on its inverse through the LU's
    solves. None when it is not square or is singular (the dense analysis names
    the rows)."""
    from scipy.sparse import diags
    from scipy.sparse.linalg import LinearOperator, splu, svds

    from symid.numeric.stability import SINGULAR_RCOND, Factor

    nc, ng = jac.shape  # type: ignore[attr-defined]
    if nc != ng or ng < 3:
        return None
    factor = Factor(jac, scaling)  # type: ignore[arg-type]
    if factor.splu is None or not factor.rcond > SINGULAR_RCOND:
        return None
    a = (diags(1.0 / scaling.row) @ jac @ diags(scaling.col)).tocsc()  # type: ignore[operator]
    lu = splu(a)
    inverse = LinearOperator((ng, ng), matvec=lu.solve, rmatvec=lambda b: lu.solve(b, trans="T"), dtype=float)
    rng = np.random.default_rng(0)  # ARPACK's start vector: the same figures every run
    smax = float(svds(a, k=1, return_singular_vectors=False, v0=rng.standard_normal(ng))[0])
    inv_max = float(svds(inverse, k=1, return_singular_vectors=False, v0=rng.standard_normal(ng))[0])
    return Rank(ng, smax * inv_max, ())


def drivers_among(layout: Layout, names: tuple[str, ...]) -> list[str]:
    """The driver constraints (motors, actuators) among `names`."""
    kinds = {c.name: c.type for c in layout.mechanism.constraints}
    return [n for n in names if kinds[n].endswith("driver")]


def redundancy_message(layout: Layout, rank: Rank) -> str:
    """The warning of a run with redundant constraints (redundant = "min_norm")."""
    drivers = drivers_among(layout, rank.dependent)
    tail = (f"; so are the drive forces of {', '.join(drivers)}" if drivers else
            "; the kinematics, the drive torques and the other reactions are unique")
    return (f"redundant constraints: the rows of {', '.join(rank.dependent)} are dependent "
            f"(rank {rank.rank} of {layout.nc} rows); their multipliers and reactions are the "
            f"minimum-norm ones, not unique{tail}")


def require_square(mech: Mechanism) -> None:
    """Generated solvers factor a square Phi_q: an input error, naming the
    dependent rows, for a mechanism with more rows than coordinates."""
    from symid.symbolic.assemble import assemble
    from symid.model.params import parameter_values

    layout = assemble(mech)
    if layout.nc > layout.ng:
        raise redundancy_error(layout, parameter_values(mech.parameters),
                                "generated solvers need as many rows as coordinates; symid solve "
                                "(redundant = \"min_norm\") solves it")


def redundancy_error(layout: Layout, values: object, hint: str) -> InputError:
    """The rows are analysed at the configuration assembled at t0 (least
    squares from q0), with the reference evaluator, so every backend and
    target reports the same names before anything is generated or compiled."""
    from symid.numeric.evaluator import Needs
    from symid.numeric.reference import ReferenceEvaluator
    from symid.model.params import initial_guess

    mech, nc, ng = layout.mechanism, layout.nc, layout.ng
    analysis = mech.analysis
    head = f"{mech.source}: [[constraint]]: {nc} constraint rows for {ng} coordinates: {nc - ng} extra"
    ev = ReferenceEvaluator(layout, values, Needs(velocity=False))  # type: ignore[arg-type]
    q0 = initial_guess(mech, values)  # type: ignore[arg-type]
    extra = _extra_driver(layout, ev, q0, analysis.t0, analysis.tol)
    if extra:
        head = f"{head}: {extra};"
    try:
        q, _ = assemble_lstsq(ev, q0, analysis.t0, analysis.tol)
    except AnalysisError as exc:
        return InputError(f"{head}{' the rows' if extra else ', and they'} cannot all hold at t0 ({exc})")
    jac = jacobian(ev, q, analysis.t0)  # sparse from SPARSE_MIN coordinates on
    rank = rank_of(jac, Scaling.of(jac, q), layout)
    if rank.rank < ng:
        hint = f"with rank {rank.rank} < {ng} a coordinate is also undriven"
    return InputError(f"{head}{'' if extra else ':'} the rows of {', '.join(rank.dependent)} are dependent at t0 "
                      f"(rank {rank.rank}); {hint}")


class _Without:
    """An evaluator's Phi and Phi_q without some rows (for assemble_lstsq)."""

    def __init__(self, ev: Evaluator, keep: np.ndarray) -> None:
        self.ev, self.keep, self.layout = ev, keep, ev.layout

    def phi(self, q: Array, t: float) -> Array:
        return self.ev.phi(q, t)[self.keep]

    def phi_q(self, q: Array, t: float) -> Array:
        return self.ev.phi_q(q, t)[self.keep]

    def phi_q_sparse(self, q: Array, t: float):  # type: ignore[no-untyped-def]
        return self.ev.phi_q_sparse(q, t).tocsr()[self.keep]  # type: ignore[attr-defined]


def _extra_driver(layout: Layout, ev: Evaluator, q0: Array, t0: float, tol: float) -> str:
    """"driver D is one too many ..." when some driver, dropped, leaves rows
    that assemble at t0 with Phi_q of full rank: D drives what the other rows
    already fix (or contradict). The last such driver in file order is named,
    and the others that would do as well; "" when none does (the extra rows
    are joints: the rank analysis names them)."""
    ng, nc = layout.ng, layout.nc
    fits = []
    for name in drivers_among(layout, tuple(c.name for c in layout.mechanism.constraints)):
        start, n = layout.row_of[name]
        if nc - n < ng:
            continue
        keep = np.array([r for r in range(nc) if not start <= r < start + n], dtype=int)
        rest = _Without(ev, keep)
        try:
            q, _ = assemble_lstsq(rest, q0, t0, tol)  # type: ignore[arg-type]
        except AnalysisError:
            continue
        jac = jacobian(rest, q, t0)
        a = _equilibrated(jac, Scaling.of(jac, q))
        if is_sparse(a):
            from symid.numeric.sparse_rank import analyse

            full = analyse(a).rank >= ng  # rank_of's threshold, with nothing nc x ng
        else:
            sv = np.linalg.svd(a, compute_uv=False)
            full = sv.size >= ng and sv[ng - 1] > max(jac.shape) * EPS * sv[0]  # rank_of's threshold
        if full:
            fits.append(name)
    if not fits:
        return ""
    if len(fits) > 1:
        return (f"driver {fits[-1]} is one too many (or {', '.join(fits[:-1])}: each alone drives what the "
                "other rows leave free)")
    return f"driver {fits[-1]} is one too many (without it the other rows drive every coordinate)"


# LSMR stops when the step's residual (or a^T of it) is this small relative to
# b (to a, b): a Gauss-Newton step that exact converges as the SVD's does.
LSMR_TOL = 1e-14


def _equilibrated(jac: Array, scaling: Scaling) -> Array:
    """Phi_q with rows divided by their norms, columns by their lengths (dense or sparse)."""
    if is_sparse(jac):
        from scipy.sparse import diags

        return (diags(1.0 / scaling.row) @ jac @ diags(scaling.col)).tocsc()  # type: ignore[no-any-return,operator]
    return jac / scaling.row[:, None] * scaling.col[None, :]


def _min_norm_step(a: Array, b: Array) -> Array:
    """The minimum-norm least-squares x of a x = b: the SVD's, singular values
    below 1e3 eps of the largest left out; sparse, LSMR's (Krylov on a and
    a^T from x = 0: the minimum-norm solution, to its tolerances)."""
    if is_sparse(a):
        from scipy.sparse.linalg import lsmr

        found = lsmr(a, b, atol=LSMR_TOL, btol=LSMR_TOL, conlim=1 / (1e3 * EPS), maxiter=10 * a.shape[1])
        return found[0]  # type: ignore[no-any-return]
    return np.linalg.lstsq(a, b, rcond=1e3 * EPS)[0]


def assemble_lstsq(ev: Evaluator, q: Array, t: float, tol: float,
                   max_iterations: int = 100) -> tuple[Array, int]:
    """Gauss-Newton on Phi(q, t) = 0 with minimum-norm (SVD) steps: assembles
    even where Phi_q is rank-deficient, for reports that must see such a
    configuration (`symid check`, the redundancy analysis).

    Raises:
        AnalysisError: no configuration within tol (scaled) reached.
    """
    scaling = Scaling.of(jacobian(ev, q, t), q)
    phi = ev.phi(q, t)
    for it in range(1, max_iterations + 1):
        floor = RULE.floor(scaling.size(q))  # the Newton rule's (symid.numeric.newton)
        res = scaling.residual(phi)
        if not np.isfinite(res):
            break
        dq = scaling.col * _min_norm_step(_equilibrated(jacobian(ev, q, t), scaling), -phi / scaling.row)
        q = q + dq
        phi = ev.phi(q, t)
        if scaling.residual(phi) <= max(tol, floor) and scaling.size(dq) <= max(tol, floor):
            return q, it
    worst = np.argsort(-np.abs(np.nan_to_num(phi / scaling.row, nan=np.inf)))[:3]
    names = ", ".join(ev.layout.constraint_names_of_rows(worst))
    raise AnalysisError(f"Newton (least squares) did not assemble the mechanism; largest residuals in: {names}", t)
