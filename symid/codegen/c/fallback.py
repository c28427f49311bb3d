"""The sparse pivoting fallback of a C solver past the dense fallback's size
(templates/c/sparse_fallback.j2): where a planned pivot fails its test at run
time, Phi_q is factored again by a left-looking sparse LU with threshold
partial pivoting (Gilbert-Peierls, as CSparse's cs_lu), in the plan's column
order and preferring the plan's pivot row, into a workspace whose size is
fixed here: O(NG + LU size) reals, never NG^2. A factorization that would
outgrow it reports SINGULAR, and symid's own loop solves that instant."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from symid.codegen.sparse import Plan

# L and U each get room for this many times the planned factors' entries
# (pivoting away from the plan can add fill), plus NG for the step in progress
CAP_FACTOR = 3


def capacity(plan: Plan, ng: int) -> int:
    """Entries of L (and of U) the fallback has room for."""
    return CAP_FACTOR * plan.size + ng


def work(plan: Plan, ng: int) -> int:
    """Reals of the fallback's workspace: the column being solved, the
    inverse row permutation, L and U (values and indices, indices held as
    reals: IWORK is NG ints by the calling convention, and a real holds an
    index exactly), their column pointers, the reach and its marks."""
    return 4 * capacity(plan, ng) + 7 * ng + 2


@dataclass(frozen=True)
class Fallback:
    """What templates/c/sparse_fallback.j2 needs (`fb`).

    Attributes:
        cap: entries of L and of U the workspace has room for.
        size: reals of the workspace (`work`).
        ap, ai, amap: Phi_q's pattern by columns: pointers, rows and the
            index of each value in Phi_q's stored order.
        q: the column order; prefer: the preferred pivot rows.
    """

    cap: int
    size: int
    ap: list[int]
    ai: list[int]
    amap: list[int]
    q: list[int]
    prefer: list[int]


def context(plan: Plan, jac: list[tuple[int, int, Any]], ng: int) -> Fallback:
    """The pattern by columns, the column order and the preferred pivot rows."""
    by_col: list[list[tuple[int, int]]] = [[] for _ in range(ng)]
    for k, (r, c, _) in enumerate(jac):
        by_col[c].append((r, k))
    ap, ai, amap = [0], [], []
    for entries in by_col:
        for r, k in sorted(entries):
            ai.append(r)
            amap.append(k)
        ap.append(len(ai))
    cols = [st.col for st in plan.steps]
    rows = [st.row for st in plan.steps]
    seen = set(cols)
    rest = [c for c in range(ng) if c not in seen]  # a structurally singular plan stops early
    used_rows = set(rows)
    return Fallback(cap=capacity(plan, ng), size=work(plan, ng), ap=ap, ai=ai or [0], amap=amap or [0],
                    q=cols + rest, prefer=rows + [r for r in range(ng) if r not in used_rows][:len(rest)])
