"""The pivot planner as it was before its heap (a rescan of every column at
every step, O(n nnz)): the reference that `symid.codegen.sparse.plan` must
match choice for choice."""

from __future__ import annotations

import numpy as np

from symid.codegen.sparse import THRESHOLD, Plan, Step


def rescanning_plan(pattern: list[tuple[int, int]], sample: np.ndarray) -> Plan:
    """Choose pivots and compute the fill for a square pattern.

    Args:
        pattern: the structural nonzeros (row, col), in slot order.
        sample: a dense n x n matrix with that pattern, used for the threshold test.

    Where the sample is numerically singular, pivots are chosen by structure
    alone; where it is structurally singular (no pivot left in some column),
    the plan is marked `singular` and the factorization always falls back.
    """
    n = sample.shape[0]
    a = {(r, c): float(sample[r, c]) for r, c in pattern}
    slots = {rc: k for k, rc in enumerate(pattern)}
    rows: dict[int, set[int]] = {r: set() for r in range(n)}
    cols: dict[int, set[int]] = {c: set() for c in range(n)}
    for r, c in pattern:
        rows[r].add(c)
        cols[c].add(r)
    steps: list[Step] = []
    for _ in range(n):
        best = None
        for c, rset in cols.items():
            if not rset:
                continue
            colmax = max(abs(a[(r, c)]) for r in rset)
            for r in rset:
                v = abs(a[(r, c)])
                if v == 0 or v < THRESHOLD * colmax:
                    continue
                cost = ((len(rows[r]) - 1) * (len(rset) - 1), -v / colmax, r, c)
                if best is None or cost < best:
                    best = cost
        if best is None:  # numerically singular sample: any structural entry will do
            for c, rset in cols.items():
                for r in rset:
                    cost = ((len(rows[r]) - 1) * (len(rset) - 1), 0.0, r, c)
                    if best is None or cost < best:
                        best = cost
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
    return Plan(n, slots, tuple(steps))
