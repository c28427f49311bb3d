"""Kinematics, inverse dynamics and statics over time.

One loop for every backend: Newton-Raphson positions warm-started from the
previous instant, then one factorization of `Phi_q` reused for qdot, qddot
and (transposed) lambda. Instants are yielded one by one so that results can
stream to a file with memory that does not grow with the run.

Robustness (see `symid.numeric.stability` and docs/analysis-options.md): every
matrix is equilibrated with scales fixed at t0; Newton takes damped steps and
reports divergence; the condition estimate of each instant's factorization is
kept (`Instant.cond`) and warned about; a solution that leaves the predicted
path for another assembly mode is caught (branch tracking).

No number without a guarantee (`symid.numeric.nonfinite`, `unexplained`, `_branch`):
an instant with an inf or NaN stops the run, naming the element; a step whose
motion the rates at both ends do not explain is continued in sub-steps and
is then a jump (an error), whole turns (followed), or an exactly singular
position (an error). The C and NumPy loops check the same and hand such an
instant to `Stepper`, so every backend reaches the same outcome.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator

import numpy as np

from symid.numeric.evaluator import Array, Evaluator
from symid.errors import AnalysisError, check_signal
from symid.model.analysis import Analysis
from symid.numeric import nonfinite
from symid.numeric.newton import RULE
from symid.numeric.redundancy import rank_of, redundancy_message
from symid.numeric.stability import SINGULAR_RCOND, Factor, Notes, Scaling, is_sparse, jacobian

if TYPE_CHECKING:  # a cached run (symid.tools.plan) solves without sympy: friction's model needs it
    from symid.numeric.friction import FrictionModel, Solved

# The Newton rule's numbers, shared with the generated loops (symid.numeric.newton).
MAX_NEWTON = RULE.max_iterations
MIN_DAMPING = RULE.min_damping  # damped steps below this fraction: diverging
NOISE = RULE.noise  # within NOISE * lim, full steps (rounding may raise the residual)
# Branch tracking: a Newton correction larger than JUMP_RATIO times the
# predicted motion of the step (and than JUMP_FLOOR, scaled) is suspicious; it
# is a jump if the continuation of the previous instant in JUMP_SUBSTEPS
# smaller steps ends more than JUMP_SAME (scaled) away.
JUMP_RATIO = 1.0
JUMP_FLOOR = 1e-7
JUMP_SUBSTEPS = 16
JUMP_SAME = 1e-6
# The same check runs on every backend from the solved instants alone (the C
# and NumPy loops hand the instant to this loop): the step's motion q1 - q0
# must be what the rates at both ends explain, the cubic Hermite
# h (qd0 + qd1) / 2 + h^2 (qdd0 - qdd1) / 12 (error h^5 q^(5) / 720). A
# mismatch above JUMP_FLOOR and UNEXPLAINED times the motion (scaled) is
# suspicious: a multiple of 2 pi, another branch, a Newton landing far from
# the prediction, rates that are not finite numbers' worth near a singular
# position. Even a coarse grid of 3 rad a step leaves 0.34 of the motion.
UNEXPLAINED = 0.5


@dataclass
class Instant:
    """The state at one output instant; absent quantities are None.

    Sizes: q, qd, qdd: (ng,); lam: (nc,); reactions: as `Evaluator.reactions`.
    cond: 1-norm condition estimate of the equilibrated Phi_q.
    """

    t: float
    q: Array
    qd: Array | None = None
    qdd: Array | None = None
    lam: Array | None = None
    reactions: Array | None = None
    cond: float = float("nan")
    iterations: int = 0
    friction: Solved | None = None  # joints with friction: their frictions (symid.numeric.friction)
    factor: Factor | None = None  # the factorization of Phi_q at q (the Python loop's): sensitivities reuse it


def _factor(ev: Evaluator, q: Array, t: float, scaling: Scaling) -> Factor:
    """The equilibrated factorization of Phi_q(q); raise if singular."""
    jac = jacobian(ev, q, t)
    if not np.isfinite(jac.data if is_sparse(jac) else jac).all():
        raise nonfinite.error(ev.layout, "Phi_q", t, q)
    factor = Factor(jac, scaling)
    if not factor.rcond > SINGULAR_RCOND:
        names = ", ".join(rank_of(jac, scaling, ev.layout, singular=True).dependent)
        cond = "inf" if factor.rcond == 0 else f"{factor.cond:.3g}"
        raise AnalysisError(f"Phi_q is singular (condition estimate {cond}); dependent constraints: {names}", t)
    return factor


def _largest(ev: Evaluator, phi: Array, scaling: Scaling) -> str:
    worst = np.argsort(-np.abs(np.nan_to_num(phi / scaling.row, nan=np.inf)))[:3]
    return ", ".join(ev.layout.constraint_names_of_rows(worst))


def newton(ev: Evaluator, q: Array, t: float, tol: float, scaling: Scaling | None = None,
           max_iterations: int = MAX_NEWTON) -> tuple[Array, int]:
    """Solve Phi(q, t) = 0 from the guess q, with damped steps.

    The rule of `symid.numeric.newton` (the generated loops' too), in the
    scaled units of `scaling`: max_i |Phi_i| / row_i and the last correction
    max_j |dq_j| / col_j within tol, floored at RULE.floor of the largest
    scaled coordinate (the correction at that times the condition estimate of
    Phi_q). Without `scaling`, one is made from Phi_q at the guess.

    Raises:
        AnalysisError: diverging (no damped step reduces |Phi|), no convergence
            in max_iterations, or Phi_q singular.
    """
    if scaling is None:
        scaling = Scaling.of(jacobian(ev, q, t), q)
    phi = ev.phi(q, t)
    res = scaling.residual(phi)
    step, cond = np.inf, 1.0
    for it in range(max_iterations + 1):
        floor = RULE.floor(scaling.size(q))
        lim = max(tol, floor)
        if not res < np.inf:
            if np.isfinite(q).all():
                raise nonfinite.error(ev.layout, "Phi", t, q)
            raise AnalysisError(f"Newton did not converge: Phi is not finite at the guess; "
                                f"in: {_largest(ev, phi, scaling)}", t)
        if res <= lim and step <= max(tol, floor * cond):
            return q, it
        if it == max_iterations:
            break
        factor = _factor(ev, q, t, scaling)
        cond = factor.cond
        dq = factor.solve(-phi)
        merit = scaling.merit(phi)
        alpha = 1.0
        while True:
            trial = q + alpha * dq
            phi_trial = ev.phi(trial, t)
            value = scaling.merit(phi_trial)
            if value <= (1 - RULE.armijo * alpha) * merit or (res <= NOISE * lim and value < np.inf):
                break
            alpha *= 0.5
            if alpha < MIN_DAMPING:
                raise AnalysisError(
                    f"Newton did not converge: diverging, no damped step reduces |Phi| (scaled max |Phi| = "
                    f"{res:.3g}): no position near the prediction satisfies the constraints; "
                    f"largest residuals in: {_largest(ev, phi, scaling)}", t)
        q, phi = trial, phi_trial
        res = scaling.residual(phi)
        step = alpha * scaling.size(dq)
    raise AnalysisError(
        f"Newton did not converge in {max_iterations} iterations (scaled max |Phi| = {res:.3g}); "
        f"largest residuals in: {_largest(ev, phi, scaling)}", t)


def run(ev: Evaluator, analysis: Analysis, q0: Array, notes: Notes | None = None) -> Iterator[Instant]:
    """Solve every output instant of `analysis`, yielding them in order.

    Args:
        ev: the evaluator (its `needs` already say which reactions to compute).
        q0: initial guess at t0, size ng.
        notes: collects the run's warnings (ill-conditioning, redundant rows,
            allowed assembly-mode jumps); read `notes.lines()` after the run.

    Raises:
        AnalysisError: with `time` and `solved` set, at the first failure.
    """
    stepper = Stepper(ev, analysis, notes)
    history: list[Array] = []
    prev: Instant | None = None
    for n, t in enumerate(_times(analysis)):
        prev = stepper.instant(n, t, prev, history, q0)
        check_signal()  # a signal whose exception C code swallowed during this instant: not yielded
        history = (history + [prev.q])[-3:]
        yield prev


class Stepper:
    """The Python loop's solve of one instant, and what the instants of one
    run share: the scaling fixed at t0, the mass diagonal and the warnings.

    A backend with a faster loop of its own hands it the instants it cannot
    vouch for (a failure, a suspected branch jump, a suspected ill-conditioning).
    """

    def __init__(self, ev: Evaluator, analysis: Analysis, notes: Notes | None = None) -> None:
        self.ev, self.analysis = ev, analysis
        self.notes = notes if notes is not None else Notes(analysis)
        groups = analysis.output_groups()
        self.statics = analysis.kind == "statics"
        self.want_lam = not analysis.kind == "kinematics" and ("lambda" in groups or "reactions" in groups)
        self.want_reactions = "reactions" in groups and analysis.kind != "kinematics"
        self.mass = ev.mass() if self.want_lam and not self.statics else None
        self.friction: FrictionModel | None = ev.friction if self.want_lam and not self.statics else None  # statics: none
        self.scaling: Scaling | None = None  # set by the first instant

    def instant(self, n: int, t: float, prev: Instant | None, history: list[Array], q0: Array) -> Instant:
        """Solve instant n (time t) after `prev` (None: assemble from q0).

        Args:
            history: the last (up to 3) positions, oldest first (the statics predictor).

        Raises:
            AnalysisError: with `time` and `solved` (= n) set.
        """
        with np.errstate(all="ignore"):  # inf and NaN are checked below, and reported
            return self._instant(n, t, prev, history, q0)

    def _instant(self, n: int, t: float, prev: Instant | None, history: list[Array], q0: Array) -> Instant:
        ev, analysis, notes = self.ev, self.analysis, self.notes
        scaling = self.scaling
        try:
            guess = None
            if prev is None or scaling is None:
                q, iterations = newton(ev, q0, t, analysis.tol)
                jac = jacobian(ev, q, t)
                scaling = self.scaling = Scaling.of(jac, q)  # fixed for the run, from the assembled t0
                if jac.shape[0] > jac.shape[1]:
                    _redundant_rows(ev, jac, scaling, notes, t)
            else:
                guess = _predict(prev, history, t)
                try:
                    q, iterations = newton(ev, guess, t, analysis.tol, scaling)
                except AnalysisError as exc:
                    # a step too long for the predictor: continue the previous
                    # instant in sub-steps (on the branch by construction)
                    try:
                        q, iterations = _continuation(ev, analysis, prev, t, scaling), 0
                        guess = q  # continued from the previous instant: on its branch
                    except AnalysisError:
                        raise exc from None
                else:
                    correction = scaling.size(q - guess)
                    if correction > JUMP_FLOOR and correction > JUMP_RATIO * scaling.size(guess - prev.q):
                        q = q if (turned := _branch(ev, analysis, prev, t, q, guess, scaling, notes, n)) is None else turned
                        guess = q  # checked
            out = self._outputs(q, t, iterations)
            notes.cond(t, out.cond, n)  # also where the check below stops the run: it says why
            if prev is not None and guess is not None and guess is not q and unexplained(prev.q, prev.qd, prev.qdd, out.q, out.qd,
                                                                   out.qdd, t - prev.t, scaling.inv_col):
                turned = _branch(ev, analysis, prev, t, q, guess, scaling, notes, n, out)
                if turned is not None:
                    out = self._outputs(turned, t, iterations)
        except AnalysisError as exc:
            exc.time, exc.solved = t, n
            raise
        return out

    def _outputs(self, q: Array, t: float, iterations: int) -> Instant:
        """The instant at the solved position q: one factorization of Phi_q for
        the rates and multipliers; an error if any value is not finite."""
        ev = self.ev
        factor = _factor(ev, q, t, self.scaling)  # type: ignore[arg-type]
        out = Instant(t=t, q=q, cond=factor.cond, iterations=iterations, factor=factor)
        if self.statics:
            if self.want_lam:
                out.lam = factor.solve_t(ev.applied(q, None, t))
        else:
            out.qd = factor.solve(ev.nu(q, t))
            out.qdd = factor.solve(ev.gamma(q, out.qd, t))
            if self.want_lam:
                rhs = ev.applied(q, out.qd, t) - self.mass * out.qdd  # type: ignore[operator]
                out.lam = factor.solve_t(rhs)
                if self.friction is not None:  # joint friction: lambda solved again with it
                    out.friction = self.friction.solve(q, out.qd, out.lam, factor, t, self.analysis.tol)
                    out.lam = out.friction.lam
        if self.want_reactions and out.lam is not None:  # with friction, its loads too
            out.reactions = ev.reactions(q, out.lam, t) if out.friction is None or self.friction is None \
                else self.friction.reactions(ev, q, out.friction, t, self.analysis.reactions)
        bad = nonfinite.not_finite(q=out.q, qd=out.qd, qdd=out.qdd, lam=out.lam, reactions=out.reactions)
        if bad:
            raise nonfinite.error(ev.layout, ", ".join(bad), t, out.q, out.qd, out.qdd)
        return out


def unexplained(q0: Array, qd0: Array | None, qdd0: Array | None, q1: Array, qd1: Array | None,
                qdd1: Array | None, h: float, c: Array) -> bool:
    """Whether the motion q1 - q0 of a step of length h is not what the rates
    at both ends explain (the cubic Hermite; see UNEXPLAINED), in the scales
    c (per coordinate). False without rates (statics)."""
    if qd0 is None or qdd0 is None or qd1 is None or qdd1 is None:
        return False
    motion = q1 - q0
    mismatch = float(np.abs((motion - 0.5 * h * (qd0 + qd1) - (h * h / 12) * (qdd0 - qdd1)) * c).max(initial=0.0))
    return mismatch > JUMP_FLOOR and not mismatch <= UNEXPLAINED * float(np.abs(motion * c).max(initial=0.0))


def _redundant_rows(ev: Evaluator, jac: Array, scaling: Scaling, notes: Notes, t: float) -> None:
    """More rows than coordinates (redundant = "min_norm"): the kinematics must
    still be determined (rank ng); name the rows whose multipliers are not unique."""
    rank = rank_of(jac, scaling, ev.layout)
    ng = jac.shape[1]
    if rank.rank < ng:
        raise AnalysisError(f"Phi_q is singular at t0 even counting the redundant rows (rank {rank.rank} "
                            f"< {ng} coordinates); dependent constraints: {', '.join(rank.dependent)}", t)
    notes.fixed.append(redundancy_message(ev.layout, rank))


def _branch(ev: Evaluator, analysis: Analysis, prev: Instant, t: float, q: Array, guess: Array,
            scaling: Scaling, notes: Notes, index: int, out: Instant | None = None) -> Array | None:
    """A suspicious step (Newton moved much further than the step's predicted
    motion or, with `out`, the motion is not what the rates at both ends
    explain: `unexplained`): continue the previous instant in smaller steps;
    ending elsewhere is an assembly-mode jump (an error, or a warning with
    assembly_jump = "warn"). Ending at q, the rates `out` solved at t must
    also explain the last sub-step: if not, they are not those of a motion
    (an exactly singular position, where they are not determined), an error.
    Ending at q but for whole turns of some angles, the run follows the
    angles continuously: returns that position (otherwise None)."""
    correction = scaling.size(q - guess)
    motion = scaling.size(guess - prev.q)
    last: list = []
    try:
        other = _continuation(ev, analysis, prev, t, scaling, last)
        gap = scaling.size(other - q)
        why = f"continuing the previous instant in {JUMP_SUBSTEPS} sub-steps ends {gap:.3g} away"
    except AnalysisError as exc:
        gap = correction if out is None else scaling.size(q - prev.q)
        why = f"and the continuation in {JUMP_SUBSTEPS} sub-steps fails ({exc}): a singular position lies between"
    else:
        turns = np.round((other - q) / (2 * np.pi)) * (np.arange(q.size) % 3 == 2)  # angles only
        if gap > JUMP_SAME and np.any(turns) and scaling.size(other - q - 2 * np.pi * turns) <= JUMP_SAME:
            return q + 2 * np.pi * turns  # the same configuration: follow the angles continuously
        if gap <= JUMP_SAME:  # the same solution: only the prediction was poor
            if out is not None and len(last) == 4 and unexplained(last[1], last[2], last[3], out.q, out.qd, out.qdd, t - last[0],
                                                                 scaling.inv_col):
                raise AnalysisError(
                    f"singular position: qdot and qddot solved here do not continue the motion even over the "
                    f"last of {JUMP_SUBSTEPS} sub-steps (condition estimate {out.cond:.3g}): Phi_q is singular "
                    f"to within rounding and the rates, multipliers and torques are not determined; take a "
                    f"motion that avoids this position", t)
            return None
    if analysis.assembly_jump == "warn":
        notes.mark("jump", t, gap, index)
        return None
    if out is not None:
        head = (f"the step moved q by {scaling.size(q - prev.q):.3g} (scaled), not what the rates at both "
                f"ends explain")
    else:
        ratio = "" if motion == 0 else f", {correction / motion:.3g} times the predicted motion of the step"
        head = f"Newton moved q by {correction:.3g} (scaled){ratio}"
    raise AnalysisError(
        f"assembly mode jump: {head}, {why}; take more steps (or set assembly_jump = \"warn\" to accept jumps)", t)


def _continuation(ev: Evaluator, analysis: Analysis, prev: Instant, t: float, scaling: Scaling,
                  last: list | None = None) -> Array:
    """q(t) reached from the previous instant in JUMP_SUBSTEPS steps; `last`
    receives the time, q, qd and qdd of the sub-step before t (with rates)."""
    q, qd, qdd = prev.q, prev.qd, prev.qdd
    h = (t - prev.t) / JUMP_SUBSTEPS
    for k in range(1, JUMP_SUBSTEPS + 1):
        tk = prev.t + k * h if k < JUMP_SUBSTEPS else t
        guess = q if qd is None or qdd is None else q + h * qd + 0.5 * h * h * qdd
        if last is not None and qd is not None and k == JUMP_SUBSTEPS:
            last[:] = [prev.t + (k - 1) * h, q, qd, qdd]
        q, _ = newton(ev, guess, tk, analysis.tol, scaling)
        if qd is not None and k < JUMP_SUBSTEPS:
            factor = _factor(ev, q, tk, scaling)
            qd = factor.solve(ev.nu(q, tk))
            qdd = factor.solve(ev.gamma(q, qd, tk))
    return q


def _times(analysis: Analysis) -> Iterator[float]:
    """`analysis.times()` one by one: a list of a million instants is 32 MB."""
    if analysis.steps == 1:
        yield analysis.t0
        return
    h = (analysis.t1 - analysis.t0) / (analysis.steps - 1)
    for k in range(analysis.steps):
        yield analysis.t0 + k * h


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


def instant_row(instant: Instant, ng: int, analysis: Analysis) -> Array:
    """One CSV row of an instant of a mechanism with ng coordinates."""
    parts: list[Array] = [np.array([instant.t])]
    for group in analysis.output_groups():
        value = {"q": instant.q, "qdot": instant.qd, "qddot": instant.qdd,
                 "lambda": instant.lam, "reactions": instant.reactions}[group]
        parts.append(np.zeros(ng) if value is None else value)
    if analysis.extra_outputs():
        parts.append(np.array([instant.cond]))
    if instant.friction is not None and "reactions" in analysis.output_groups():  # after every other column
        parts.append(instant.friction.columns())
    return np.concatenate(parts)
