"""Evaluation forms of expressions that round less.

Absolute coordinates can be large (the far end of a 100 m ladder) while the
constraint residual they enter is tiny. `x_i + A_i s_i - x_j - A_j s_j`
summed left to right rounds a partial sum to the ulp of the coordinates, so
Newton can only drive Phi down to ~1e-14 there, and along a chain of bodies
these residuals add up to position errors of ~1e-12.

`grouped` makes every sum add its trig-free terms (coordinates, fixed
offsets, driver functions) first, as one parenthesized group: the
coordinates of joined bodies are close, so their difference is exact
(Sterbenz), and the body-fixed terms then round relative to the residual
itself. Applied to what is evaluated, never to what is differentiated.
"""

from __future__ import annotations

from typing import Any

import sympy as sp


class Grouped(sp.Function):
    """Grouped(e): the value of e, computed on its own before the sum it is in.

    Printers print it as `(e)`; lambdify and CasADi evaluate the identity.
    """

    nargs = 1
    is_real = True
    _imp_ = staticmethod(lambda x: x)  # what lambdify calls

    @classmethod
    def eval(cls, arg: Any) -> None:
        return None


def grouped(expr: sp.Expr) -> sp.Expr:
    """expr with the trig-free terms of every sum mixing both kinds grouped."""
    if not expr.args or isinstance(expr, sp.Symbol):
        return expr
    args = [grouped(a) for a in expr.args]
    if expr.is_Add:
        plain = [a for a in args if not a.has(sp.sin, sp.cos)]
        if len(plain) >= 2 and len(plain) < len(args):
            return sp.Add(Grouped(sp.Add(*plain)), *[a for a in args if a.has(sp.sin, sp.cos)])
    return expr.func(*args) if args != list(expr.args) else expr
