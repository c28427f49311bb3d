"""Many variants through the generated NumPy module, vectorized over variants.

The module's public functions (phi, phi_q_values, nu, gamma, applied, mass,
reactions) broadcast: with q of shape (NG, K) and p of shape (NP, K) they
evaluate K variants at one instant in one call. So the K variants of a chunk
advance together instant by instant, as the module's own loop (`_rows`)
advances one: its predictor, its Newton (full steps, the convergence rule of
`symid.numeric.newton.RULE`), Phi_q factored in its fixed pivot order
(`symid.study.batch_lu`, one elimination for all K), then the rates,
multipliers and reactions. Python's work per instant is a few hundred array
operations for the whole chunk, none per variant.

t0 is assembled from q0 by the same Newton, and the scales of the checks
are fixed there, as the Python loop (`Stepper`) does before the module's
loop takes over; a variant whose assembly the Python loop would damp (a full
step that does not lower the scaled residual enough) goes back. A variant
goes back (status RETRY) at any instant the module's loop hands over: Newton
fails, a pivot fails its threshold test, the scaled pivots spread wider
than its screen (the condition may be near the warning level), a value is
not finite, or the branch checks (Newton moved far from the prediction; the
step's motion is not what the rates at both ends explain). The engine
re-runs such a variant through the normal path, so it ends exactly as
`symid solve` ends.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from symid.errors import check_signal
from symid.backends import Array, Needs, friction
from symid.backends.numpy_backend import SCREEN, NumpyEvaluator
from symid.backends.prepare import needs_of, prepare
from symid.model.mechanism import Mechanism
from symid.model.params import base_names
from symid.numeric.stability import ARM_FLOOR
from symid.numeric.newton import EPS, RULE
from symid.numeric.solve import JUMP_FLOOR, JUMP_RATIO, UNEXPLAINED
from symid.numeric.stability import requested
from symid.output.results import columns
from symid.study.batch_lu import Factors, Plan
from symid.study.variants import Measure
from symid.study.vector_figures import Figures, Values
from symid.symbolic.assemble import Layout, assemble

# Variants advanced together: the work per instant is a few hundred array
# operations whatever K is, so larger chunks run faster (1000 variants: 4x
# the instants per second of 64), as long as a chunk's stored columns
# (K x instants x the figures' columns) stay within BUDGET bytes.
MAX_CHUNK = 1024
BUDGET = 64 * 2**20
RETRY = 1  # status of a variant the vectorized loop hands back to the normal path


@dataclass
class Batch:
    """What the vectorized loop returned for K variants.

    Attributes:
        names: figure names (contract order); values: (K, len(names));
        status: (K,) 0 ok, RETRY: decide through the normal path;
        t_end: (K,) the last instant's time; solved: (K,) instants solved;
        solve_s: wall seconds of the solve (t0 assemblies and the vectorized loop).
    """

    names: tuple[str, ...]
    values: Array
    status: Array
    t_end: Array
    solved: Array
    solve_s: float = 0.0


def usable(mechanism: Mechanism) -> bool:
    """Whether the module's own loop runs this analysis (`NumpyEvaluator.own_loop`):
    a square Phi_q, no stability feature only the Python loop provides, and
    no joint friction (solved by the Python loop only)."""
    layout = assemble(mechanism)
    return not requested(mechanism.analysis) and layout.nc == layout.ng and not friction.solved(mechanism)


def run(mechanism: Mechanism, full: Array, chunk: int | None = None) -> Batch:
    """Solve the variants `full` (K, NP base parameters) of `mechanism` (the
    study's, `study_mechanism`) in chunks of `chunk` (default: as many as
    MAX_CHUNK and BUDGET allow), vectorized over each."""
    needs = needs_of(mechanism)
    solver = prepare(mechanism, "numpy", Needs(velocity=needs.velocity, reactions=needs.reactions, batch=True,
                                               friction=False))
    layout = solver.layout
    module = cast(NumpyEvaluator, solver.evaluator).module  # the evaluator's own instance: see _stack
    setattr(module, "_stack", _stack)  # the generated module defines it: replaced in this private copy
    figures = Figures(Measure(mechanism, columns(layout, mechanism.analysis)))
    if chunk is None:
        per_variant = 8 * mechanism.analysis.steps * len(figures.columns)
        chunk = max(1, min(MAX_CHUNK, BUDGET // per_variant))
    order = base_names(mechanism.parameters)
    pick = [order.index(n) for n in module.PARAMS]
    k = len(full)
    values = np.full((k, len(figures.names)), np.nan)
    status = np.zeros(k, dtype=np.intc)
    t_end = np.full(k, np.nan)
    solved = np.zeros(k, dtype=np.int64)
    tick = time.perf_counter()
    if len(module.PIVOT_ROWS) < module.NG:  # no fixed pivot order: the module's loop hands over every instant
        return Batch(figures.names, values, np.full(k, RETRY, dtype=np.intc), t_end, solved)
    for s in range(0, k, chunk):
        e = min(k, s + chunk)
        part = _Chunk(mechanism, layout, module, full[s:e], pick, figures.columns)
        part.solve()
        status[s:e], solved[s:e] = part.status, part.solved
        ok = np.flatnonzero(part.status == 0)
        values[s + ok] = figures(part.data[ok], part.values, ok)
        t_end[s + ok] = part.data[ok, -1, 0]
    return Batch(figures.names, values, status, t_end, solved, time.perf_counter() - tick)


class _Chunk:
    """K variants advanced together; `solve` fills `data` (K, steps, the
    figures' columns), `status` and `solved`."""

    def __init__(self, mech: Mechanism, layout: Layout, module: Any, full: Array, pick: list[int],
                 cols: list[int]) -> None:
        self.mech, self.layout, self.m, self.cols = mech, layout, module, cols
        self.values = Values(mech, full)
        self.p = np.ascontiguousarray(full[:, pick].T)  # (NP, K): the module's p, one column per variant
        a = mech.analysis
        k, ng, nc = len(full), layout.ng, layout.nc
        self.data = np.full((k, a.steps, len(cols)), np.nan)
        self.status = np.where(self.values.finite, 0, RETRY).astype(np.intc)
        self.solved = np.zeros(k, dtype=np.int64)
        self.velocity = a.kind != "statics"
        self.multipliers = a.kind != "kinematics"
        self.q = self.values.of([x for b in mech.bodies for x in b.q0])  # (NG, K): q0, then the latest q
        self.qd = np.zeros((ng, k))
        self.qdd = np.zeros((ng, k))
        self.inv_col = np.ones((ng, k))
        self.dr = np.ones((k, nc))
        self.dc = np.ones((k, ng))

    def solve(self) -> None:
        a = self.mech.analysis
        live = np.flatnonzero(self.status == 0)
        h = (a.t1 - a.t0) / (a.steps - 1) if a.steps > 1 else 0.0
        with np.errstate(all="ignore"):  # inf and NaN are checked, and hand the variant back
            self._first(live)
            live = live[self.status[live] == 0]
            history = [self.q.copy()]
            for k in range(1, a.steps):
                if not live.size:
                    break
                history = self._step(k, a.t0 + k * h, h, live, history)
                live = live[self.status[live] == 0]
                check_signal()

    def _first(self, live: Array) -> None:
        """t0: Newton from q0 as the Python loop assembles (it damps a step that
        does not lower the scaled residual enough: such a variant goes back),
        then the scales of the checks, fixed at the assembled q, as `Stepper`."""
        m, a = self.m, self.mech.analysis
        p, guess = self.p[:, live], self.q[:, live]
        inv_col, inv_row, _, _ = _scales(_dense(m, guess, a.t0, p), guess)
        q, ok = _newton(m, guess.copy(), a.t0, p, a.tol, (inv_row, inv_col))
        self.inv_col[:, live], _, self.dr[live], self.dc[live] = _scales(_dense(m, q, a.t0, p), q)
        out, good = self._outputs(q, a.t0, p, live)
        self._keep(0, a.t0, live, ok & good, out)

    def _step(self, k: int, t: float, h: float, live: Array, history: list[Array]) -> list[Array]:
        """Instant k (time t) of the variants `live`, from the module loop's
        predictor; flagged ones get RETRY. Returns the statics' history."""
        m, a = self.m, self.mech.analysis
        p = self.p[:, live]
        q1 = self.q[:, live]
        if self.velocity:  # the module's _predict: o + h d + hh e
            guess = q1 + h * self.qd[:, live] + (0.5 * h * h) * self.qdd[:, live]
        else:  # the polynomial through the last positions, as the module's loop
            past = [x[:, live] for x in history]
            guess = (3 * past[0] - 3 * past[1] + past[2] if len(past) >= 3 else
                     2 * past[0] - past[1] if len(past) == 2 else past[0])
        q, ok = _newton(m, guess.copy(), t, p, a.tol)
        out, good = self._outputs(q, t, p, live)
        ok &= good
        c = self.inv_col[:, live]
        ok &= ~_moved(q, guess, q1, c)
        if self.velocity:
            ok &= ~_unexplained(q1, self.qd[:, live], self.qdd[:, live], q, out["qdot"], out["qddot"], h, c)
        self._keep(k, t, live, ok, out)
        return history if self.velocity else [self.q.copy()] + history[:2]  # latest first, up to 3

    def _outputs(self, q: Array, t: float, p: Array, live: Array) -> tuple[dict[str, Array], Array]:
        """The rates, multipliers and reactions at the solved q (NG, K'), and
        which variants the module's loop would vouch for: finite, its fixed
        pivots pass, and their scaled spread is within its screen."""
        m, a = self.m, self.mech.analysis
        out = {"q": q}
        factors = _factor(m, q, t, p)
        scaled = factors.pivots() * self.dr[live][:, m.PIVOT_ROWS].T * self.dc[live][:, m.PIVOT_COLS].T
        ok = factors.ok & (scaled.max(axis=0) / scaled.min(axis=0) <= a.cond_threshold / SCREEN)
        qd = qdd = None
        if self.velocity:
            qd = factors.solve(m.nu(q, t, p))
            qdd = factors.solve(m.gamma(q, qd, t, p))
            out["qdot"], out["qddot"] = qd, qdd
        if self.multipliers:
            if self.velocity:
                mass = np.asarray(m.mass(p))
                rhs = m.applied(q, qd, t, p) - (mass[:, None] if mass.ndim == 1 else mass) * qdd
            else:
                rhs = m.applied(q, None, t, p)
            masses = np.broadcast_to(np.asarray(m.mass(p), dtype=float).reshape(m.NG, -1)[0::3], (m.NG // 3, q.shape[1]))
            mixed = masses.min(axis=0) * m.REFINE_SPREAD < masses.max(axis=0)  # the module's _mixed, per variant
            lam = out["lambda"] = factors.refine_t(rhs, factors.solve_t(rhs), mixed)
            if m.NR:
                out["reactions"] = np.broadcast_to(m.reactions(q, lam, t, p), (m.NR, q.shape[1]))
        ok &= np.isfinite(sum(x.sum(axis=0) for x in out.values()))  # the module's finite_sum
        return out, ok

    def _keep(self, k: int, t: float, live: Array, ok: Array, out: dict[str, Array]) -> None:
        """Store instant k (time t) of the variants live[ok]; the others go back."""
        q = out["q"]
        n = q.shape[1]
        zeros = np.zeros((self.layout.ng, n))
        parts = [np.full((1, n), t)]
        parts += [out.get(g, zeros) for g in self.mech.analysis.output_groups()]
        row = np.concatenate(parts, axis=0)[self.cols].T
        self.data[live[ok], k] = row[ok]
        self.solved[live[ok]] += 1
        self.status[live[~ok]] = RETRY
        self.q[:, live] = q
        if self.velocity:
            self.qd[:, live], self.qdd[:, live] = out["qdot"], out["qddot"]


def _dense(m: Any, q: Array, t: float, p: Array) -> Array:
    """Phi_q of each variant, (K, NC, NG)."""
    out = np.zeros((q.shape[1], m.NC, m.NG))
    out[:, m.PHI_Q_ROWS, m.PHI_Q_COLS] = np.broadcast_to(m.phi_q_values(q, t, p), (m.NNZ, q.shape[1])).T
    return out


def _stack(values: list[Any], like: Any) -> Array:
    """The module's `_stack` (its outputs as one array of the instants'
    shape), the same numbers without a `broadcast_to` per output: on K
    variants that helper, not the arithmetic, was half of each call."""
    shape = np.broadcast_shapes(np.shape(like), *[np.shape(v) for v in values])
    out = np.empty((len(values),) + shape)
    for k, v in enumerate(values):
        out[k] = v
    return out


def _factor(m: Any, q: Array, t: float, p: Array) -> Factors:
    """Phi_q of each variant factored in the module's pivot order."""
    plan = m.__dict__.get("_symid_batch_plan")
    if plan is None:  # the structure is the module's: worked out once
        plan = m._symid_batch_plan = Plan(m.PHI_Q_ROWS, m.PHI_Q_COLS, m.PIVOT_ROWS, m.PIVOT_COLS)
    return Factors(plan, np.broadcast_to(m.phi_q_values(q, t, p), (m.NNZ, q.shape[1])), m.THRESHOLD)


def _newton(m: Any, q: Array, t: float, p: Array, tol: float,
            guard: tuple[Array, Array] | None = None) -> tuple[Array, Array]:
    """The module's Newton (`_instant`) on every column of q (NG, K) at once:
    full steps, converged when max |Phi| and the last correction are within
    lim (or |Phi| was where that correction was computed). Returns the
    positions and which variants converged.

    guard: (inv_row (NC, K), inv_col (NG, K)), the scales at the guess: a
    variant fails where the Python loop (`symid.numeric.solve.newton`) would
    not take the full step (Armijo on the scaled merit): it would damp it.
    """
    n = q.shape[1]
    lim = np.maximum(tol, RULE.floor_ulps * EPS * np.maximum(1.0, np.abs(q).max(axis=0)))
    step = np.full(n, np.inf)
    r = np.broadcast_to(m.phi(q, t, p), (m.NC, n)).copy()
    rmax = np.abs(r).max(axis=0)
    done = np.zeros(n, dtype=bool)
    bad = np.zeros(n, dtype=bool)
    for it in range(RULE.max_iterations + 1):
        bad |= ~done & ~np.isfinite(rmax + r.sum(axis=0))
        done |= ~bad & (rmax <= lim) & (step <= lim)
        live = ~done & ~bad
        if not live.any():
            break
        if it == RULE.max_iterations:
            bad |= live
            break
        factors = _factor(m, q[:, live], t, p[:, live])
        dq = factors.solve(r[:, live])
        bad[live] |= ~factors.ok  # the module would take its dense fallback: hand it over
        if guard is not None:
            bad[live] |= ~_full_step(m, q[:, live], r[:, live], q[:, live] - dq, t, p[:, live], tol,
                                     guard[0][:, live], guard[1][:, live])
        q[:, live] -= dq
        step[live] = np.abs(dq).max(axis=0)
        # |Phi| was within lim where this correction was computed, and the correction is too
        done |= live & (rmax <= lim) & (step <= lim)
        again = live & ~done
        if again.any():
            r[:, again] = np.broadcast_to(m.phi(q[:, again], t, p[:, again]), (m.NC, int(again.sum())))
            rmax[again] = np.abs(r[:, again]).max(axis=0)
    return q, done & ~bad


def _moved(q: Array, g: Array, o: Array, c: Array) -> Array:
    """The module's `_moved`: Newton moved q from the guess g by more than
    JUMP_FLOOR and JUMP_RATIO times the predicted motion g - o (scaled by c)."""
    correction = (np.abs(q - g) * c).max(axis=0)
    return (correction > JUMP_FLOOR) & (correction > JUMP_RATIO * (np.abs(g - o) * c).max(axis=0))


def _unexplained(o: Array, d: Array, e: Array, q: Array, v: Array, w: Array, h: float, c: Array) -> Array:
    """The module's `_unexplained`: the motion q - o of a step h is not the
    cubic Hermite of the rates at both ends, by more than JUMP_FLOOR and
    UNEXPLAINED times the motion (scaled by c)."""
    mismatch = (np.abs(q - o - (0.5 * h) * (d + v) - (h * h / 12.0) * (e - w)) * c).max(axis=0)
    return (mismatch > JUMP_FLOOR) & ~(mismatch <= UNEXPLAINED * (np.abs(q - o) * c).max(axis=0))


def _full_step(m: Any, q: Array, r: Array, trial: Array, t: float, p: Array, tol: float, inv_row: Array,
               inv_col: Array) -> Array:
    """Whether the Python loop's Newton takes the full step q -> trial: the
    scaled merit falls by the Armijo fraction, or |Phi| is within noise."""
    scaled = r * inv_row
    merit = np.sqrt(np.sum(scaled * scaled, axis=0))
    after = np.broadcast_to(m.phi(trial, t, p), r.shape) * inv_row
    value = np.sqrt(np.sum(after * after, axis=0))
    lim = np.maximum(tol, RULE.floor_ulps * EPS * np.maximum(1.0, np.abs(q * inv_col).max(axis=0)))
    res = np.abs(scaled).max(axis=0)
    return (value <= (1 - RULE.armijo) * merit) | ((res <= RULE.noise * lim) & (value < np.inf))


def _scales(jac: Array, q: Array) -> tuple[Array, Array, Array, Array]:
    """`Scaling.of` for K variants: Phi_q (K, NC, NG) at q (NG, K) -> 1 / col
    (NG, K), 1 / row (NC, K), and the powers of two dr (K, NC), dc (K, NG)."""
    ng = jac.shape[2]
    rot = np.arange(ng) % 3 == 2
    lin = np.abs(jac[:, :, ~rot]).max(axis=2, initial=0.0)
    turn = np.abs(jac[:, :, rot]).max(axis=2, initial=0.0)
    # rows with both kinds of entries: the ratio is a moment arm; their median
    arms = np.where((lin > 0) & (turn > 0), turn / np.where(lin > 0, lin, 1.0), np.nan)
    # as stability.reference_length: arms that vanish against the largest are left out
    with np.errstate(invalid="ignore"):
        largest = np.nanmax(np.where(np.isnan(arms), -np.inf, arms), axis=1, keepdims=True)
        arms = np.where(arms >= ARM_FLOOR * largest, arms, np.nan)
    some = ~np.all(np.isnan(arms), axis=1)
    lref = np.zeros(len(jac))
    if some.any():
        lref[some] = np.nanmedian(arms[some], axis=1)
    lref = np.where(lref > 0, lref, np.abs(q[~rot]).max(axis=0, initial=0.0))
    lref = np.where((lref > 0) & np.isfinite(lref), lref, 1.0)
    col = np.where(rot[None, :], 1.0, lref[:, None])
    row = np.abs(jac * col[:, None, :]).max(axis=2, initial=0.0)
    row = np.where((row > 0) & np.isfinite(row), row, 1.0)
    two = lambda x: np.exp2(np.round(np.log2(x)))  # noqa: E731 (as stability._power_of_two)
    return (1.0 / col).T, (1.0 / row).T, 1.0 / two(row), two(col)
