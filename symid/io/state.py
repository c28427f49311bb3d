"""State functions in a force's expressions: `x(B) y(B) phi(B) vx(B) vy(B) omega(B)`.

A `point_force`'s `F` or a `torque`'s `T` may read the state of any body B
(a drag `-c*vx(cart)*abs(vx(cart))`, a friction torque with the sign of the
motion), and use `abs` and `sign`. Each expression is split into its terms of
t (kept as the force's function of time, as before) and its terms of the state
(which may not contain t: written g(state) + f(t)). The state terms are
written on the generic symbols of the force family (its own body as role i,
every other body it reads as b1, b2, ..., each parameter as a constant c_k)
and become the element's variant, so the derivation, every backend and the
sensitivities treat them as any family's expressions of q and qd.
"""

from __future__ import annotations

from typing import Any, Callable

import sympy as sp

from symid.errors import InputError
from symid.model.mechanism import GROUND, T
from symid.symbolic import symbols as s
from symid.symbolic.forces import STATE_CONSTANT

Fail = Callable[[str, str], InputError]
# state function -> (q or qd, component)
FUNCTIONS = {"x": (0, 0), "y": (0, 1), "phi": (0, 2), "vx": (1, 0), "vy": (1, 1), "omega": (1, 2)}
TYPES = ("point_force", "torque")  # the families whose expressions may read the state
KINKS = {"abs": (1, sp.Abs), "sign": (1, sp.sign)}


def marker(body: str) -> sp.Symbol:
    """A body's name where a state function takes it (no file can name it: a leading _)."""
    return sp.Symbol("_body_" + body, real=True)


def placeholder(function: str, body: str) -> sp.Symbol:
    return sp.Symbol(f"_state_{function}_{body}", real=True)


def functions(bodies: list[str]) -> dict[str, Any]:
    """The state functions and abs, sign, for the parser; `bodies`: the body names."""
    by_marker = {marker(b): b for b in bodies}

    def build(name: str) -> Callable[[sp.Expr], sp.Expr]:
        def state(arg: sp.Expr) -> sp.Expr:
            if arg not in by_marker:
                raise ValueError(f"takes a body's name (bodies: {', '.join(bodies)})")
            return placeholder(name, by_marker[arg])
        return state

    return {**{n: (1, build(n)) for n in FUNCTIONS}, **KINKS}


def names(bodies: list[str]) -> dict[str, sp.Symbol]:
    """Body name -> its marker, the names a state function's argument may be."""
    return {b: marker(b) for b in bodies}


def check(expr: sp.Expr, bodies: list[str], where: str, fail: Fail) -> None:
    """A body's name anywhere but in a state function is refused."""
    for b in bodies:
        if expr.has(marker(b)):
            raise fail(where, f"the body name '{b}' is only an argument of a state function "
                       f"({', '.join(f'{f}({b})' for f in FUNCTIONS)})")


def generalize(values: dict[str, Any], keys: tuple[str, ...], own: str, bodies: list[str],
               parameters: set[sp.Symbol], where: str, fail: Fail) -> tuple[dict[str, Any], dict[str, Any], dict[str, str]]:
    """Split a force's expressions (`values[k]` for k in `keys`, in order) into
    terms of t and terms of the state.

    Returns the values (each key's terms of t, and `constants`: the
    parameters the state terms use, as c_0, c_1, ...), the options (`state`:
    the state terms on generic symbols) and the extra roles (b1 -> body name).
    Nothing changes (({}, {}, {})) when no expression reads the state.
    """
    exprs = [e for k in keys for e in (values[k] if isinstance(values[k], tuple) else (values[k],))]
    states = {placeholder(f, b): (f, b) for f in FUNCTIONS for b in bodies}
    if not any(isinstance(e, sp.Basic) and e.free_symbols & set(states) for e in exprs):
        return {}, {}, {}
    timed, state_terms = [], []
    for e, k in zip(exprs, [k for k in keys for _ in (values[k] if isinstance(values[k], tuple) else (0,))]):
        if not isinstance(e, sp.Basic):  # a tabled function of t: no state in it
            state_terms.append(sp.Integer(0))
            timed.append(e)
            continue
        g, h = [], []
        for term in sp.Add.make_args(e):
            if term.free_symbols & set(states):
                if term.has(T):
                    raise fail(f"{where} key '{k}'", f"the term {term} mixes t and the state: write the "
                               "expression as g(state) + f(t)")
                g.append(term)
            else:
                h.append(term)
        state_terms.append(sp.Add(*g))
        timed.append(sp.Add(*h))
    roles: dict[str, str] = {own: "i"}
    for e in state_terms:
        for node in sp.preorder_traversal(e):
            if node in states and states[node][1] not in roles:
                roles[states[node][1]] = f"b{len(roles)}"
    order: list[sp.Symbol] = []
    for e in state_terms:
        for node in sp.preorder_traversal(e):
            if node in parameters and node not in order:
                order.append(node)  # type: ignore[arg-type]
    sub: dict[sp.Basic, sp.Basic] = {p: s.scalar(f"{STATE_CONSTANT}{k}") for k, p in enumerate(order)}
    for x, (f, b) in states.items():
        which, c = FUNCTIONS[f]
        sub[x] = (s.q if which == 0 else s.qd)(roles[b])[c] if b in roles else x
    # as written (placeholders for the state, `placeholder`): for what shows an element, and tests
    out: dict[str, Any] = {"constants": tuple(order), "written": tuple(exprs)}
    n = 0
    for k in keys:
        if isinstance(values[k], tuple):
            out[k] = tuple(timed[n:n + len(values[k])])
            n += len(values[k])
        else:
            out[k] = timed[n]
            n += 1
    extra = {role: body for body, role in roles.items() if role != "i"}
    assert GROUND not in extra.values()
    return out, {"state": sp.Tuple(*(e.xreplace(sub) for e in state_terms))}, extra
