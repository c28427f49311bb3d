"""Reading an expression constraint's rows (`type = "expression"`, key `phi`).

Each row is parsed by the file's whitelist parser (never evaluated) over
`x_i y_i phi_i` (and `x_j y_j phi_j` when `j` is given), `t`, the parameters
and the signals, then checked for what would make its derivation meaningless:
a kink (abs, sign) where Phi_q and gamma are taken, a state function (those are
for forces), a row of no coordinate, a driver row not of the form g(q) - f(t).
Whether the rows are independent is judged at q0, once the bodies are known
(`check_rank`).
"""

from __future__ import annotations

import re
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.errors import InputError
from symid.model.mechanism import GROUND, T, Element
from symid.model.params import to_float
from symid.symbolic import symbols as s
from symid.symbolic.constraints.expression import KINKS, generic

Fail = Callable[[str, str], InputError]
STATE_FUNCTIONS = ("x", "y", "phi", "vx", "vy", "omega")
_STATE_CALL = re.compile(r"\b(" + "|".join(STATE_FUNCTIONS) + r")\s*\(")
_KINK_CALL = re.compile(r"\b(abs|sign)\s*\(")


def placeholder(name: str) -> sp.Symbol:
    """A coordinate's stand-in while a row is read (no file can name it: a leading _)."""
    return sp.Symbol("_" + name, real=True)


def coordinates(roles: Sequence[str]) -> dict[str, sp.Symbol]:
    """The names a row may use for the coordinates of its bodies -> their placeholders."""
    return {f"{c}_{role}": placeholder(f"{c}_{role}") for role in roles for c in s.COORDS}


def refuse_state(text: Any, where: str, fail: Fail, why: str) -> None:
    """Refuse a state function `x(B)`... in text where only forces may use one (`why` says so)."""
    if isinstance(text, str) and (m := _STATE_CALL.search(text)):
        raise fail(where, f"{m.group(1)}() at column {m.start() + 1} is a state function, allowed in forces only: {why}")


def read(raw: Any, where: str, bodies: Mapping[str, str], params: Mapping[str, sp.Symbol],
         parse: Callable[[Any, str, Mapping[str, sp.Expr]], sp.Expr], fail: Fail,
         ) -> tuple[dict[str, Any], dict[str, Any]]:
    """(values, options) of an expression constraint from its `phi` list.

    Args:
        raw: the file's `phi` value; where: "constraint 'NAME' key 'phi'".
        bodies: role -> body name as read (j absent: ground, no j coordinates).
        parse: (value, where, names) -> expression of `names`, t, parameters, signals.
    """
    if not isinstance(raw, list) or not raw:
        shown = "an empty list" if raw == [] else f"{type(raw).__name__} {raw!r}"[:60]
        raise fail(where, f"must be a list of expressions, one per constraint row, not {shown}")
    roles = ("i", "j") if "j" in bodies else ("i",)
    names = coordinates(roles)
    rows: list[sp.Expr] = []
    for n, text in enumerate(raw):
        at = f"{where} row {n + 1}"
        if isinstance(text, str):
            refuse_state(text, at, fail, f"a constraint row is written in {', '.join(names)} directly")
            if m := _KINK_CALL.search(text):
                raise fail(at, f"{m.group(1)}() at column {m.start() + 1} is not differentiable at 0, and a "
                           "constraint row is differentiated twice (Phi_q, gamma): write the row without it")
        row = parse(text, at, names)
        if row.has(*KINKS):  # a motion law's kink or a signal's
            raise fail(at, "is not differentiable everywhere (abs, sign or a step in it), and a constraint row "
                       "is differentiated twice (Phi_q, gamma)")
        used = row.free_symbols & set(names.values())
        if not used:
            raise fail(at, f"depends on no coordinate ({', '.join(names)}): a row must constrain the bodies")
        if row.has(T):
            for term in sp.Add.make_args(row):
                if term.has(T) and term.free_symbols & set(names.values()):
                    raise fail(at, f"the term {term} mixes t and the coordinates: a driver row is written "
                               "g(coordinates) - f(t) (its effort is then the actuator's)")
        rows.append(row)
    if sum(1 for r in rows if r.has(T)) > 1 or (len(rows) > 1 and any(r.has(T) for r in rows)):
        raise fail(where, "a row with t is a driver: give each driver row a constraint of its own, "
                   "without other rows (its effort is then one column)")
    to_generic = {names[f"{c}_{role}"]: s.q(role)[k] for role in roles for k, c in enumerate(s.COORDS)}
    form, constants, f = generic(rows, to_generic, set(params.values()), T)
    values: dict[str, Any] = {"phi": tuple(r.xreplace(to_generic) for r in rows), "constants": constants}
    if f is not None:
        values["f"] = f
    return values, {"phi": form}


def check_rank(element: Element, q0: Mapping[str, Sequence[sp.Expr]], t0: float,
               values: Mapping[sp.Symbol, float], source: str) -> None:
    """Refuse rows of one expression constraint that are dependent at q0, naming them."""
    rows = element.values["phi"]
    if len(rows) < 2:  # type: ignore[arg-type]
        return
    at: dict[sp.Symbol, float] = dict(values)
    unknowns: list[sp.Symbol] = []
    for role, body in element.bodies.items():
        for k, c in enumerate(s.q(role)):
            if body == GROUND:
                at[c] = 0.0
            else:
                at[c] = to_float(q0[body][k], values)
                unknowns.append(c)
    at[T] = t0
    jac = np.array([[float(sp.diff(r, u).xreplace({k: sp.Float(v, 17) for k, v in at.items()}).evalf())
                     for u in unknowns] for r in rows], dtype=float)  # type: ignore[union-attr]
    scale = max(float(np.abs(jac).max()), 1e-300)
    tol = 1e-10 * scale  # far above a double's rounding of the gradients, far below a real dependence
    for n in range(1, len(jac)):
        if np.linalg.matrix_rank(jac[: n + 1], tol=tol) < n + 1:  # the first row the earlier ones span
            raise InputError(f"{source}: constraint '{element.name}' key 'phi': row {n + 1} depends on "
                             f"row{'s' if n > 1 else ''} {', '.join(str(k + 1) for k in range(n))} at q0 "
                             "(their gradients in the coordinates are dependent there): the constraint "
                             "removes fewer freedoms than it has rows")
