"""Variants whose masses or inertias are negative are bad input, as in a file.

`symid solve --set m=-2` is refused (exit 2) by the reader; a sweep or an
optimization sets the same base parameters without the reader, so a variant
with a negative mass would be solved and reported `ok`. This checks every
variant's masses and inertias at once, vectorized over the variants.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
import sympy as sp

from symid.errors import InputError
from symid.model.mechanism import INERTIALS, Mechanism, parameter_symbol
from symid.model.params import parameter_values
from symid.text import number

Array = np.ndarray


def checker(mechanism: Mechanism, names: Sequence[str]) -> Callable[[Array], tuple[int, str] | None]:
    """`first_negative` for these varied names, lambdified once (an optimizer asks at every point)."""
    base = parameter_values(mechanism.parameters)
    derived: dict[sp.Symbol, sp.Expr] = {}
    for name, expr in mechanism.parameters.items():  # dependency order: a definition reads earlier ones
        if expr.free_symbols:
            derived[parameter_symbol(name)] = expr.xreplace(derived)
    varied = [parameter_symbol(n) for n in names]
    tests = []  # (body, key, args, function) of each mass or inertia that a variant moves
    for body in mechanism.bodies:
        for key in INERTIALS:
            expr = sp.sympify(getattr(body, key)).xreplace(derived)
            if expr.free_symbols & set(varied):  # else fixed for every variant: the reader checked it
                args = sorted(expr.free_symbols, key=str)
                # a module object, not "numpy" (which runs `from numpy import *`: numpy.f2py, .testing, .ma)
                tests.append((body.name, key, args, sp.lambdify(args, expr, [np])))

    def first(values: Array) -> tuple[int, str] | None:
        values = np.asarray(values, dtype=float).reshape(-1, len(names))
        columns = {s: values[:, k] for k, s in enumerate(varied)}
        worst: tuple[int, str] | None = None
        for body, key, args, f in tests:
            with np.errstate(all="ignore"):
                got = np.broadcast_to(f(*(columns.get(a, base.get(a)) for a in args)), len(values))
            bad = np.flatnonzero(got < 0)
            if bad.size and (worst is None or bad[0] < worst[0]):
                worst = (int(bad[0]), f"body '{body}' key '{key}' is {number(float(got[bad[0]]))}")
        return worst

    return first


def first_negative(mechanism: Mechanism, names: Sequence[str], values: Array) -> tuple[int, str] | None:
    """(variant index, "body 'B' key 'mass' is -2") of the first variant with a
    negative mass or inertia, or None; `values` has one row per variant, one
    column per name in `names` (base parameters; derived ones follow them)."""
    return checker(mechanism, names)(values)


def check(mechanism: Mechanism, names: Sequence[str], values: Array, option: str) -> None:
    """Refuse (InputError, exit 2) the first variant with a negative mass or inertia."""
    found = first_negative(mechanism, names, values)
    if found is not None:
        k, what = found
        row = np.asarray(values, dtype=float).reshape(-1, len(names))[k]
        at = ", ".join(f"{n} = {number(float(v))}" for n, v in zip(names, row))
        raise InputError(f"{mechanism.source}: {option}: variant {k} ({at}): {what}, which must not be negative")
