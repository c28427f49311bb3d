"""Numeric values of a mechanism's parameters and of its expressions."""

from __future__ import annotations

import math
from typing import Mapping

import sympy as sp

from symid.model import parameter_symbol


def order_parameters(exprs: Mapping[str, sp.Expr]) -> list[str]:
    """Names in an order where each comes after the parameters it uses.

    Raises:
        ValueError: naming the parameters on a cycle.
    """
    symbols = {parameter_symbol(n): n for n in exprs}
    deps = {n: {symbols[x] for x in e.free_symbols if x in symbols} for n, e in exprs.items()}
    done: list[str] = []
    state: dict[str, int] = {}
    for start in exprs:
        stack = [(start, iter(sorted(deps[start])))]
        if state.get(start) == 2:
            continue
        state[start] = 1
        while stack:
            name, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                stack.pop()
                state[name] = 2
                done.append(name)
            elif state.get(nxt) == 1:
                cycle = [n for n, _ in stack[[n for n, _ in stack].index(nxt):]] + [nxt]
                raise ValueError(" -> ".join(cycle))
            elif state.get(nxt) != 2:
                state[nxt] = 1
                stack.append((nxt, iter(sorted(deps[nxt]))))
    return done


def parameter_values(exprs: Mapping[str, sp.Expr]) -> dict[sp.Symbol, float]:
    """Evaluate every parameter (given in dependency order) to a float.

    Raises:
        ValueError: (name, message) when a value is not a finite real number.
    """
    values: dict[sp.Symbol, float] = {}
    for name, expr in exprs.items():
        values[parameter_symbol(name)] = to_float(expr, values, name)
    return values


def to_float(expr: sp.Expr, values: Mapping[sp.Symbol, float], what: str = "value") -> float:
    """A finite float from an expression of parameters with known values."""
    try:
        number = complex(sp.N(expr.xreplace({k: sp.Float(v) for k, v in values.items()}), 17))
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(what, f"is not a number ({exc})") from None
    if number.imag != 0 and abs(number.imag) > 1e-300:
        raise ValueError(what, "is not a real number")
    if not math.isfinite(number.real):
        raise ValueError(what, "is not finite")
    return number.real
