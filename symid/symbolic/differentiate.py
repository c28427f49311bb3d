"""Partial derivatives of many expressions by many symbols, with sympy's own results.

`sympy.diff(e, x)` walks all of `e` for every `x`, and each level of its
recursion recomputes the `free_symbols` of the subtree below it (not cached)
and asks whether the result is zero. A Jacobian of family residuals (tens of
rows sharing most subtrees, tens of arguments) spends most of its time there.

`Differentiator.diff(e, x)` gives the very expression `e.diff(x)` gives: it
applies, for Add, Mul, Pow and the plain functions (sin, cos, atan2, ...),
the rule their class's `_eval_derivative` applies (the same constructors, the
same arguments in the same order), and asks sympy itself for any other node.
What it saves: each subtree's free symbols are found once (a derivative by
a symbol not among them is 0 without a walk) and each (subtree, symbol)
derivative is built once however many rows or columns share it.
"""

from __future__ import annotations

from typing import Sequence

import sympy as sp
from sympy.core.basic import Basic
from sympy.core.function import ArgumentIndexError, Function
from sympy.ntheory.multinomial import multinomial_coefficients_iterator

_BASIC_N_TIMES = Basic._eval_derivative_n_times
_MUL_N_TIMES = sp.Mul._eval_derivative_n_times
_ADD_D = sp.Add._eval_derivative
_POW_D = sp.Pow._eval_derivative
_FUNCTION_D = Function._eval_derivative


def _rule(cls: type) -> str:
    """Which of sympy's rules `cls` differentiates by ("" when none mirrored here)."""
    if cls is sp.Mul or (issubclass(cls, sp.Mul) and cls._eval_derivative_n_times is _MUL_N_TIMES):
        return "mul"
    if cls._eval_derivative_n_times is not _BASIC_N_TIMES:
        return ""
    derivative = getattr(cls, "_eval_derivative", None)
    if derivative is _ADD_D:
        return "add"
    if derivative is _POW_D:
        return "pow"
    if derivative is _FUNCTION_D and issubclass(cls, Function):
        return "function"
    return ""


class Differentiator:
    """Memoized first derivatives by symbols, equal (==, same tree) to `expr.diff(symbol)`."""

    def __init__(self) -> None:
        self._free: dict[sp.Basic, frozenset[sp.Basic]] = {}
        self._memo: dict[tuple[sp.Basic, sp.Symbol], sp.Expr] = {}
        self._rules: dict[type, str] = {}

    def free(self, e: sp.Basic) -> frozenset[sp.Basic]:
        """e.free_symbols, each subtree's found once."""
        out = self._free.get(e)
        if out is None:
            if e.is_Symbol:
                out = frozenset((e,))
            elif e.is_Atom or type(e).free_symbols is not Basic.free_symbols:
                out = frozenset(e.free_symbols)  # Atoms, and nodes that bind symbols (a Derivative, a Lambda)
            else:
                out = frozenset().union(*(self.free(a) for a in e.args))
            self._free[e] = out
        return out

    def diff(self, e: sp.Expr, x: sp.Symbol) -> sp.Expr:
        """d e / d x, as `e.diff(x)` gives it."""
        key = (e, x)
        out = self._memo.get(key)
        if out is None:
            out = self._diff(e, x)
            self._memo[key] = out
        return out

    def _diff(self, e: sp.Expr, x: sp.Symbol) -> sp.Expr:
        if x not in self.free(e):
            return sp.S.Zero
        cls = type(e)
        rule = self._rules.get(cls)
        if rule is None:
            rule = self._rules[cls] = _rule(cls)
        if rule == "add":  # Add._eval_derivative
            return e.func(*[self.diff(a, x) for a in e.args])
        if rule == "mul":  # Mul._eval_derivative_n_times(x, 1): the Leibniz rule, factor by factor
            terms = []
            for kvals, c in multinomial_coefficients_iterator(len(e.args), 1):
                p = sp.Mul(*[self.diff(a, x) if k else a for k, a in zip(kvals, e.args)])
                terms.append(c * p)
            return sp.Add(*terms)
        if rule == "pow":  # Pow._eval_derivative
            dbase = self.diff(e.base, x)
            dexp = self.diff(e.exp, x)
            return e * (dexp * sp.log(e.base) + dbase * e.exp / e.base)
        if rule == "function":  # Function._eval_derivative
            terms = []
            for i, a in enumerate(e.args, start=1):
                da = self.diff(a, x)
                if da.is_zero:
                    continue
                try:
                    df = e.fdiff(i)
                except ArgumentIndexError:
                    df = Function.fdiff(e, i)
                terms.append(df * da)
            return sp.Add(*terms)
        return e.diff(x)

    def jacobian(self, exprs: Sequence[sp.Expr], args: Sequence[sp.Symbol]) -> sp.Matrix:
        """`Matrix(exprs).jacobian(args)`, element for element."""
        rows = [sp.sympify(e) for e in exprs]
        return sp.Matrix(len(rows), len(args), [self.diff(e, x) for e in rows for x in args])
