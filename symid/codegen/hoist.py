"""Parameter-only subexpressions, computed once per parameter vector.

`m_rod*L_rod^2/12`, `4*pi^2*n^2`, the parameter factors of a product or a
sum: whatever reads only parameters is the same at every instant. `hoist`
replaces each (largest such piece, shared across all expressions) by a new
symbol `p[NP + j]`, so that generated code reads it from an extended
parameter vector that a prepare step fills once: [p, hoisted values].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import sympy as sp

from symid.symbolic.differentiate import Differentiator


def _is_param(sym: sp.Basic) -> bool:
    return isinstance(sym, sp.Symbol) and sym.name.startswith("p[")


def _param_only(e: sp.Basic) -> bool:
    """Whether e reads parameters and nothing else (no q, qd, t, lam)."""
    free = e.free_symbols
    return bool(free) and all(_is_param(s) for s in free)


def _worth(e: sp.Basic) -> bool:
    """Whether computing e costs more than reading it: not an atom, not a
    number times an atom (one multiply either way, or a negation)."""
    if e.is_Atom:
        return False
    if e.is_Mul and len(e.args) == 2 and any(a.is_Number for a in e.args) and all(a.is_Atom for a in e.args):
        return False
    return True


@dataclass
class Hoisted:
    """The hoisted pieces: values[j] is printed as p[np + j]."""

    np: int
    values: list[sp.Expr] = field(default_factory=list)
    index: dict[sp.Expr, sp.Symbol] = field(default_factory=dict)
    # each subtree's free symbols found once (`_param_only` recomputes them at every level of the walk)
    free: Differentiator = field(default_factory=Differentiator)

    def param_only(self, e: sp.Basic) -> bool:
        """`_param_only(e)`, from each subtree's free symbols found once."""
        free = self.free.free(e)
        return bool(free) and all(_is_param(s) for s in free)

    def symbol(self, e: sp.Expr) -> sp.Symbol:
        if e not in self.index:
            self.index[e] = sp.Symbol(f"p[{self.np + len(self.values)}]", real=True)
            self.values.append(e)
        return self.index[e]

    def walk(self, e: sp.Expr) -> sp.Expr:
        """e with its largest parameter-only pieces replaced."""
        if e.is_Atom or not isinstance(e, sp.Expr):  # a condition, a pair: left whole
            return e
        if isinstance(e, sp.Piecewise):  # its pieces and conditions stay together
            return self.symbol(e) if self.param_only(e) else e
        if self.param_only(e):
            return self.symbol(e) if _worth(e) else e
        args = [self.walk(a) for a in e.args]
        if e.is_Add or e.is_Mul:  # the parameter-only factors or terms, as one piece
            plain = [a for a, old in zip(args, e.args) if self.param_only(old)]
            if len(plain) >= 2:
                piece = e.func(*[old for old in e.args if self.param_only(old)])
                if _worth(piece):
                    rest = [a for a, old in zip(args, e.args) if not self.param_only(old)]
                    return e.func(self.symbol(piece), *rest)
        return e.func(*args) if args != list(e.args) else e


def hoist(groups: Sequence[Sequence[sp.Expr]], np_: int) -> tuple[list[list[sp.Expr]], list[sp.Expr]]:
    """Each list of expressions with its parameter-only pieces replaced by
    p[np_ + j], and the pieces (j order)."""
    h = Hoisted(np_)
    out = [[h.walk(sp.sympify(e)) for e in exprs] for exprs in groups]
    return out, h.values
