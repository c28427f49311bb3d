"""The user's own constraint: rows written as expressions (`type = "expression"`).

The file's rows are expressions of `x_i y_i phi_i x_j y_j phi_j`, `t` and the
parameters. Each is stored in a generic form that the derivation shares with
every row of the same shape: body coordinates as the generic symbols of
`symid.symbolic.symbols`, each parameter as a constant `c_k` (numbered in order
of appearance; its value, the parameter, is the element's
`values["constants"][k]`), and a driver row `g(q) - f(t)` with its time part
as the driver function `f` (the element's `values["f"]`), as for the built-in
drivers. The reactions are reported at `si` on i and `sj` on j by the
reference's virtual-work formula, which holds for any point.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import sympy as sp

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, Key, body, point

NAME = "expression"
CONSTANT = "c_"
# what the rows may not contain where Phi_q and gamma are derived: not differentiable at 0
KINKS = (sp.Abs, sp.sign, sp.Heaviside)


def constant(k: int) -> sp.Symbol:
    """The generic symbol of a row's k-th parameter."""
    return s.scalar(f"{CONSTANT}{k}")


def _rows(options: Mapping[str, Any]) -> tuple[sp.Expr, ...]:
    return tuple(options["phi"])


def _shape(options: Mapping[str, Any]) -> tuple[int, tuple[sp.Symbol, ...]]:
    rows = _rows(options)
    used = sp.Tuple(*rows).free_symbols
    count = sum(1 for x in used if x.name.startswith(CONSTANT))
    return len(rows), tuple(constant(k) for k in range(count))


expression = ConstraintType(
    name=NAME,
    keys=(body("i"), body("j", default="ground"), Key("phi", "rows"), point("si", default=[0, 0]),
          point("sj", default=[0, 0])),
    points={"i": "si", "j": "sj"},
    phi=lambda o: list(_rows(o)),
    shape=_shape,
)

TYPES = (expression,)


def generic(rows: Sequence[sp.Expr], coordinates: Mapping[sp.Symbol, sp.Symbol], parameters: set[sp.Symbol],
            time: sp.Symbol) -> tuple[sp.Tuple, tuple[sp.Symbol, ...], sp.Expr | None]:
    """The rows' generic form, the parameters standing for c_0, c_1, ... and
    the driver's f(t) (None: no row has t).

    Args:
        rows: the rows as read: `coordinates` (placeholder -> generic body
            coordinate), parameter symbols and `time`; a driver row is already
            known to be separable, g(q) + h(t) (see `split`).
        parameters: the parameter symbols.
    """
    parts = [split(row, time) for row in rows]
    order: list[sp.Symbol] = []
    for g, _ in parts:
        for node in sp.preorder_traversal(g):
            if node in parameters and node not in order:
                order.append(node)  # type: ignore[arg-type]
    sub: dict[sp.Basic, sp.Basic] = dict(coordinates)
    sub.update({p: constant(k) for k, p in enumerate(order)})
    out, f = [], None
    for g, h in parts:
        if h != 0:
            f = -h
            out.append(g.xreplace(sub) - s.F_SERIES[0])
        else:
            out.append(g.xreplace(sub))
    return sp.Tuple(*out), tuple(order), f


def split(row: sp.Expr, time: sp.Symbol) -> tuple[sp.Expr, sp.Expr]:
    """(g, h) with row = g + h, h the terms with t (and nothing else of the
    coordinates' symbols is checked here: `mixed` says which terms have both)."""
    g, h = [], []
    for term in sp.Add.make_args(row):
        (h if term.has(time) else g).append(term)
    return sp.Add(*g), sp.Add(*h)
