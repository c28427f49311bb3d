"""A sparse LU whose pivot order and fill are fixed at generation time.

`plan` chooses pivots by Markowitz cost among entries that pass a threshold
test on a sample matrix (Phi_q at the assembled configuration), and records
every operation; targets emit them as straight-line code. At run time each
fixed pivot is checked against the same threshold, and a configuration where
it fails falls back to a pivoting factorization.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Sequence

import numpy as np

THRESHOLD = 0.1  # a pivot must be >= THRESHOLD * the largest entry of its column
# The generated solvers refine lambda (one step of iterative refinement of the
# transposed solve) where the bodies' masses span more than this: there a light
# body's multipliers would carry a heavy one's rounding (issue 26: a 2 g part on a
# 1 t boom, 1e-9 of its own loads); with uniform scales they are at rounding without it.
REFINE_SPREAD = 100.0


@dataclass(frozen=True)
class Step:
    """One elimination step.

    Attributes:
        row, col: the pivot's position in the original matrix.
        below: rows eliminated later that have an entry in `col` (their
            multipliers are stored in place of that entry).
        right: columns pivoted later in which `row` has an entry (U's row).
    """

    row: int
    col: int
    below: tuple[int, ...]
    right: tuple[int, ...]


@dataclass(frozen=True)
class Plan:
    """The factorization of an n x n pattern.

    Attributes:
        slots: (row, col) -> index into the factor array; the first entries
            are the original pattern in the given order, fill follows.
        steps: the elimination steps in order.
    """

    n: int
    slots: dict[tuple[int, int], int]
    steps: tuple[Step, ...]
    singular: bool = False

    @property
    def size(self) -> int:
        return len(self.slots)

    @property
    def fill(self) -> int:
        return len(self.slots)


def plan(pattern: Sequence[tuple[int, int]], sample: np.ndarray | Sequence[float], n: int | None = None) -> Plan:
    """Choose pivots and compute the fill for a square pattern.

    Args:
        pattern: the structural nonzeros (row, col), in slot order.
        sample: the matrix's values for the threshold test: a dense n x n
            array, or (for large systems, nothing n x n) one value per
            pattern entry, with n given.

    At each step the pivot is the entry of least Markowitz cost
    (r_count - 1)(c_count - 1) among those within THRESHOLD of their
    column's largest, ties to the larger |entry| / column max, then the
    lower row and column. Each column keeps its best candidate in a heap,
    recomputed only where a step changed it (the pivot row's columns and the
    columns of the rows it updates; stale heap entries are skipped by a
    version count): cost linear in the fill for a banded pattern, where
    rescanning every column at every step was O(n nnz).

    Where the sample is numerically singular, pivots are chosen by structure
    alone; where it is structurally singular (no pivot left in some column),
    the plan is marked `singular` and the factorization always falls back.
    """
    if isinstance(sample, np.ndarray) and sample.ndim == 2:
        n = sample.shape[0]
        a = {(r, c): float(sample[r, c]) for r, c in pattern}
    else:
        if n is None:
            raise ValueError("plan: per-entry sample values need n")
        a = {rc: float(v) for rc, v in zip(pattern, sample)}
    slots = {rc: k for k, rc in enumerate(pattern)}
    rows: dict[int, set[int]] = {r: set() for r in range(n)}
    cols: dict[int, set[int]] = {c: set() for c in range(n)}
    for r, c in pattern:
        rows[r].add(c)
        cols[c].add(r)
    version = dict.fromkeys(cols, 0)
    numeric: list[tuple[tuple[int, float, int, int], int]] = []     # (cost, version) by threshold
    structural: list[tuple[tuple[int, float, int, int], int]] = []  # (cost, version) by structure

    def rank(c: int) -> None:
        """Push column c's best candidates under a new version."""
        version[c] += 1
        rset = cols[c]
        if not rset:
            return
        lc = len(rset) - 1
        colmax = max(abs(a[(r, c)]) for r in rset)
        best = sbest = None
        for r in rset:
            mk = (len(rows[r]) - 1) * lc
            s = (mk, 0.0, r, c)
            if sbest is None or s < sbest:
                sbest = s
            v = abs(a[(r, c)])
            if v == 0 or v < THRESHOLD * colmax:
                continue
            cost = (mk, -v / colmax, r, c)
            if best is None or cost < best:
                best = cost
        if best is not None:
            heapq.heappush(numeric, (best, version[c]))
        assert sbest is not None
        heapq.heappush(structural, (sbest, version[c]))

    def top(heap: list[tuple[tuple[int, float, int, int], int]]) -> tuple[int, float, int, int] | None:
        while heap:
            cost, ver = heap[0]
            c = cost[3]
            if c in cols and version[c] == ver:
                return cost
            heapq.heappop(heap)
        return None

    for c in cols:
        rank(c)
    steps: list[Step] = []
    for _ in range(n):
        best = top(numeric)
        if best is None:  # numerically singular sample: any structural entry will do
            best = top(structural)
        if best is None:
            return Plan(n, slots, tuple(steps), singular=True)
        _, _, pr, pc = best
        below = tuple(sorted(cols[pc] - {pr}))
        right = tuple(sorted(rows[pr] - {pc}))
        piv = a[(pr, pc)] or 1.0  # the sample only guides the choice
        for r in below:
            a[(r, pc)] /= piv
            for c in right:
                if (r, c) not in a:
                    a[(r, c)] = 0.0
                    slots[(r, c)] = len(slots)
                    rows[r].add(c)
                    cols[c].add(r)
                a[(r, c)] -= a[(r, pc)] * a[(pr, c)]
        for r in cols[pc]:
            rows[r].discard(pc)
        for c in rows[pr]:
            cols[c].discard(pr)
        del cols[pc]
        del rows[pr]
        steps.append(Step(pr, pc, below, right))
        dirty = set(right)
        for r in below:
            dirty |= rows[r]
        for c in dirty:
            rank(c)
    return Plan(n, slots, tuple(steps))


def factor(p: Plan, values: np.ndarray) -> np.ndarray | None:
    """Execute the plan on the pattern's values (reference for the emitted code).

    Returns:
        the factor array, or None where a fixed pivot fails the threshold test.
    """
    if p.singular:
        return None
    lu = np.zeros(p.size)
    lu[: len(values)] = values
    s = p.slots
    for st in p.steps:
        piv = lu[s[(st.row, st.col)]]
        colmax = max([abs(piv)] + [abs(lu[s[(r, st.col)]]) for r in st.below])
        if not abs(piv) >= THRESHOLD * colmax or piv == 0:
            return None
        for r in st.below:
            lu[s[(r, st.col)]] /= piv
            m = lu[s[(r, st.col)]]
            for c in st.right:
                lu[s[(r, c)]] -= m * lu[s[(st.row, c)]]
    return lu


def solve(p: Plan, lu: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b, from the factors (reference for the emitted code)."""
    s = p.slots
    y = b.astype(float).copy()
    for st in p.steps:
        for r in st.below:
            y[r] -= lu[s[(r, st.col)]] * y[st.row]
    x = np.zeros(p.n)
    for st in reversed(p.steps):
        acc = y[st.row] - sum(lu[s[(st.row, c)]] * x[c] for c in st.right)
        x[st.col] = acc / lu[s[(st.row, st.col)]]
    return x


def solve_transposed(p: Plan, lu: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A^T x = b, from the same factors."""
    s = p.slots
    z = np.zeros(p.n)  # indexed by pivot row
    for st in p.steps:
        acc = b[st.col] - sum(lu[s[(prev.row, st.col)]] * z[prev.row] for prev in _above(p, st))
        z[st.row] = acc / lu[s[(st.row, st.col)]]
    x = z.copy()
    for st in reversed(p.steps):
        x[st.row] -= sum(lu[s[(r, st.col)]] * x[r] for r in st.below)
    return x


def _above(p: Plan, st: Step) -> list[Step]:
    """Earlier steps whose U row has an entry in st.col."""
    return [prev for prev in p.steps if prev is not st and st.col in prev.right]


# --- constants fixed at generation time ----------------------------------------------

@dataclass(frozen=True)
class Known:
    """A factor-array value fixed at generation time (a constant entry of
    Phi_q, such as a revolute's +-1 in x and y, and what follows from it)."""

    value: float


Coef = int | Known  # a factor-array slot read at run time, or a value known when generating


@dataclass(frozen=True)
class FoldedStep:
    """One elimination step with what the constants decide already decided.

    Attributes:
        step: the step of the plan; pivot_slot: its pivot's slot.
        pivot: the pivot's value where it is known (else None: lu[pivot_slot]).
        test: "pass" or "fail" where the threshold test is decided by known
            values; else (the largest known |entry| of the column, pivot
            included, or 0.0; the column's slots read at run time).
        scale: the multipliers computed at run time, (slot, source): lu[slot]
            = source * (1 / pivot).
        updates: (target, t, m, s): lu[target] = t - m * s at run time.
        reciprocal, below, right: what the solves read: 1 / pivot, L's
            column (row, coef) and U's row (col, coef).
    """

    step: Step
    pivot_slot: int
    pivot: float | None
    test: str | tuple[float, tuple[int, ...]]
    scale: tuple[tuple[int, Coef], ...]
    updates: tuple[tuple[int, Coef, Coef, Coef], ...]
    reciprocal: Coef
    below: tuple[tuple[int, Coef], ...]
    right: tuple[tuple[int, Coef], ...]


def fold(p: Plan, values: list[float | None]) -> list[FoldedStep]:
    """Run the plan at generation time on the values that are known.

    values: per pattern slot, the entry of Phi_q where it is a number, else
    None (fill starts at 0). Every operation whose operands are all known is
    done here, in the floating-point operations of run time (the factors
    are bitwise the same); the rest is left for run time, with the known
    operands as numbers. A slot is final once its own step is done, so the
    solves read each entry as it stands then.
    """
    val: list[float | None] = [*values, *[0.0] * (p.size - len(values))]
    s = p.slots

    def coef(k: int) -> Coef:
        v = val[k]
        return k if v is None else Known(v)

    out = []
    for st in p.steps:
        ps = s[(st.row, st.col)]
        piv = val[ps]
        column = [s[(r, st.col)] for r in st.below]
        known_max = max((abs(v) for v in (val[k] for k in [ps, *column]) if v is not None), default=0.0)
        unknown = tuple(k for k in column if val[k] is None)
        test: str | tuple[float, tuple[int, ...]]
        if piv == 0.0:
            test = "fail"
        elif piv is not None and not unknown:
            test = "pass" if abs(piv) >= THRESHOLD * known_max else "fail"
        else:
            test = (known_max, unknown)
        recip = 1.0 / piv if piv is not None and piv != 0 else None
        val[ps] = recip
        scale: list[tuple[int, Coef]] = []
        updates: list[tuple[int, Coef, Coef, Coef]] = []
        for r in st.below:
            m = s[(r, st.col)]
            mv = val[m]
            if recip is not None and mv is not None:
                val[m] = mv * recip
            else:
                scale.append((m, coef(m)))
                val[m] = None
            for c in st.right:
                t, u = s[(r, c)], s[(st.row, c)]
                tv, mv, uv = val[t], val[m], val[u]
                if mv == 0.0 or uv == 0.0:
                    continue  # t - 0 u = t
                if tv is not None and mv is not None and uv is not None:
                    val[t] = tv - mv * uv
                else:
                    updates.append((t, coef(t), coef(m), coef(u)))
                    val[t] = None
        out.append(FoldedStep(st, ps, piv, test, tuple(scale), tuple(updates), coef(ps),
                              tuple((r, coef(s[(r, st.col)])) for r in st.below),
                              tuple((c, coef(s[(st.row, c)])) for c in st.right)))
    return out
