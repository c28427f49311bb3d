"""Numeric values of a mechanism's parameters and of its expressions."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable, Mapping

import numpy as np
import sympy as sp

from symid.model.mechanism import Mechanism, parameter_symbol


def order_parameters(exprs: Mapping[str, sp.Expr], symbol: Callable[[str], sp.Symbol] = parameter_symbol
                     ) -> list[str]:
    """Names in an order where each comes after the names it uses (`symbol(name)`
    stands for a name in the expressions: a parameter's symbol, a signal's placeholder).

    Raises:
        ValueError: naming the parameters on a cycle.
    """
    symbols = {symbol(n): n for n in exprs}
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
    global _last_values
    given = dict(exprs)
    last = _last_values
    if last is not None and last[0] == given:  # equal expressions (mostly the same objects): equal values
        return dict(last[1])
    values: dict[sp.Symbol, float] = {}
    for name, expr in given.items():
        values[parameter_symbol(name)] = to_float(expr, values, name)
    _last_values = (given, values)
    return dict(values)


# The latest parameter_values: the steps of one solve (the solve, its warnings,
# its figures and their gradients) each ask again for the same variant's
# values, 2 ms each; one entry, compared by content, is a pure function's memo.
_last_values: tuple[dict[str, sp.Expr], dict[sp.Symbol, float]] | None = None


_MATH = {
    sp.sin: math.sin, sp.cos: math.cos, sp.tan: math.tan, sp.asin: math.asin, sp.acos: math.acos,
    sp.atan: math.atan, sp.sinh: math.sinh, sp.cosh: math.cosh, sp.tanh: math.tanh, sp.exp: math.exp,
    sp.log: math.log, sp.atan2: math.atan2,
}


def to_float(expr: sp.Expr, values: Mapping[sp.Symbol, float], what: str = "value") -> float:
    """A finite float from an expression of parameters with known values.

    Evaluated in double precision node by node (not by arbitrary-precision
    evalf, which can run for ever on `exp(exp(exp(100)))`): an overflow, a
    domain error or a non-real result is an error naming `what`.

    Raises:
        ValueError: (what, message).
    """
    expr = sp.sympify(expr)
    if expr.is_number and expr.is_real is False:  # sympy folds log(-1) to I*pi when it reads it
        raise ValueError(what, f"is not a real number (it is {sp.sstr(expr)})")
    try:
        number = _evaluate(expr, values)
    except (OverflowError, ZeroDivisionError):
        raise ValueError(what, "is not finite") from None
    except (ValueError, TypeError) as exc:
        raise ValueError(what, f"is not a real number ({exc})") from None
    if not math.isfinite(number):
        raise ValueError(what, "is not finite")
    return number


def _evaluate(e: sp.Basic, values: Mapping[sp.Symbol, float]) -> float:
    if e.is_Number or e.is_NumberSymbol:
        return float(e)
    if e.is_Symbol:
        if e not in values:
            raise ValueError(f"no value for {e}")
        return values[e]  # type: ignore[index]
    args = [_evaluate(a, values) for a in e.args]
    if e.is_Add:
        return math.fsum(args)
    if e.is_Mul:
        return math.prod(args)
    if e.is_Pow:
        base, exponent = args
        if base < 0 and not float(exponent).is_integer():
            raise ValueError("a negative number to a fractional power")
        return float(base**exponent) if base != 0 or exponent >= 0 else math.inf
    func: Any = _MATH.get(e.func)  # type: ignore[call-overload]
    if func is None:
        raise TypeError(f"cannot evaluate {e.func}")
    return float(func(*args))


def is_derived(expr: sp.Expr) -> bool:
    """Whether a parameter's value is an expression of other parameters (a
    derived parameter); a number, or an expression of numbers only, is base.

    Only base parameters are inputs (`--set`, sweeps, the `p` of generated
    code); a derived one is always recomputed from its definition.
    """
    return bool(sp.sympify(expr).free_symbols)


def base_names(parameters: Mapping[str, sp.Expr]) -> tuple[str, ...]:
    """The base parameters' names, in the mechanism's order."""
    return tuple(n for n, e in parameters.items() if not is_derived(e))


def without_values(mechanism: Mechanism) -> Mechanism:
    """The mechanism with its base parameters' values left out (None): all that
    its layout and its generated code depend on. Two variants that differ in
    base parameter values only compare equal (`==`)."""
    parameters = {n: (e if is_derived(e) else None) for n, e in mechanism.parameters.items()}
    return dataclasses.replace(mechanism, parameters=parameters)  # type: ignore[arg-type]


def initial_guess(mechanism: Mechanism, values: Mapping[sp.Symbol, float]) -> np.ndarray:
    """The bodies' `q0` at the parameter `values`, size ng (3 per body)."""
    return np.array([to_float(v, values) for b in mechanism.bodies for v in b.q0])
