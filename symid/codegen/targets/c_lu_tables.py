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
    return out
