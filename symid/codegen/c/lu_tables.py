"""The elimination plan as index tables, for a sparse LU that loops over
them (templates/c/sparse_lu_tables.j2) instead of one statement per
operation: code of fixed size for any mechanism, at the cost of the
generation-time folding of known values (`sparse.fold`). The operations and
their order are those of the unfolded straight-line code (which also skips
updates by a known zero)."""

from __future__ import annotations

from typing import Any

from symid.codegen.sparse import Plan


def _csr(lists: list[list[int]]) -> tuple[list[int], list[int]]:
    ptr, flat = [0], []
    for items in lists:
        flat += items
        ptr.append(len(flat))
    return ptr, flat


def lu_tables(plan: Plan) -> dict[str, Any]:
    """Per step (in order): pivot row, column and slot; L's column (rows,
    slots), U's row (columns, slots), the update targets (below x right,
    row-major) and the earlier steps' U entries in the step's column (rows,
    slots), each as pointer and index arrays."""
    s = plan.slots
    above: dict[int, list[tuple[int, int]]] = {}
    for st in plan.steps:
        for c in st.right:
            above.setdefault(c, []).append((st.row, s[(st.row, c)]))
    out: dict[str, Any] = {"steps": len(plan.steps),
                           "row": [st.row for st in plan.steps], "col": [st.col for st in plan.steps],
                           "piv": [s[(st.row, st.col)] for st in plan.steps]}
    for key, lists in (
        ("below_row", [list(st.below) for st in plan.steps]),
        ("below_slot", [[s[(r, st.col)] for r in st.below] for st in plan.steps]),
        ("right_col", [list(st.right) for st in plan.steps]),
        ("right_slot", [[s[(st.row, c)] for c in st.right] for st in plan.steps]),
        ("update", [[s[(r, c)] for r in st.below for c in st.right] for st in plan.steps]),
        ("above_row", [[r for r, _ in above.get(st.col, [])] for st in plan.steps]),
        ("above_slot", [[k for _, k in above.get(st.col, [])] for st in plan.steps]),
    ):
        ptr, flat = _csr(lists)
        out[key] = flat or [0]  # C has no empty arrays
        out[key.split("_")[0] + "_ptr"] = ptr
    out.update(_flat(plan, out))
    return out


def _flat(plan: Plan, t: dict[str, Any]) -> dict[str, Any]:
    """Per-entry tables for loops that need no per-step bookkeeping: the
    steps have one or two entries each, so a loop per step costs more than
    its arithmetic. below_src: the pivot row of each L entry's step (the
    forward solve is then one loop over L); upd_a, upd_b: the two factors
    of each update (slots of L and U); tb_*: L's entries with the steps in
    reverse and each step's entries in order, for the transposed back
    solve, which subtracts in the same order as the per-step loop did."""
    steps, bp, rp = plan.steps, t["below_ptr"], t["right_ptr"]
    src = [st.row for k, st in enumerate(steps) for _ in range(bp[k], bp[k + 1])]
    upd_a, upd_b = [], []
    for k in range(len(steps)):
        for i in range(bp[k], bp[k + 1]):
            for j in range(rp[k], rp[k + 1]):
                upd_a.append(t["below_slot"][i])
                upd_b.append(t["right_slot"][j])
    order = [i for k in reversed(range(len(steps))) for i in range(bp[k], bp[k + 1])]
    owner = [steps[k].row for k in range(len(steps)) for _ in range(bp[k], bp[k + 1])]
    out = {"below_src": src or [0], "upd_a": upd_a or [0], "upd_b": upd_b or [0], "n_below": len(src),
           "tb_dst": [owner[i] for i in order] or [0], "tb_slot": [t["below_slot"][i] for i in order] or [0],
           "tb_src": [t["below_row"][i] for i in order] or [0]}
    out.update(_scaled(plan, t))
    return out


def _scaled(plan: Plan, t: dict[str, Any]) -> dict[str, Any]:
    """Per-entry tables for the two solves that scale each step's sum by its
    pivot (U x = y, U^T L^T x = b's first half): every step's sum is kept
    unscaled in its pivot row, and an entry that reads an earlier sum scales
    it there (the same product, so the same double the per-step loop kept);
    one pass scales them all at the end. bk_*: U's entries, steps in
    reverse; tf_*: the earlier steps' U entries of each step's column."""
    steps, rp, ap = plan.steps, t["right_ptr"], t["above_ptr"]
    by_col = {st.col: k for k, st in enumerate(steps)}
    by_row = {st.row: k for k, st in enumerate(steps)}
    bk = [(steps[k].row, t["right_slot"][j], steps[by_col[t["right_col"][j]]].row, t["piv"][by_col[t["right_col"][j]]])
          for k in reversed(range(len(steps))) for j in range(rp[k], rp[k + 1])]
    tf = [(steps[k].row, t["above_slot"][i], t["above_row"][i], t["piv"][by_row[t["above_row"][i]]])
          for k in range(len(steps)) for i in range(ap[k], ap[k + 1])]
    out: dict[str, Any] = {"n_right": len(bk), "n_above": len(tf)}
    for prefix, entries in (("bk", bk), ("tf", tf)):
        for n, key in enumerate(("dst", "slot", "src", "piv")):
            out[f"{prefix}_{key}"] = [e[n] for e in entries] or [0]
    return out
