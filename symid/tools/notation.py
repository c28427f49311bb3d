"""The hand notation of docs/symbols.md for printed expressions: one table of
(Unicode, LaTeX) names for the generic symbols, and the printers that use it."""

from __future__ import annotations

import re

import sympy as sp
from sympy.printing.latex import LatexPrinter
from sympy.printing.pretty.pretty import PrettyPrinter
from sympy.printing.pretty.stringpict import prettyForm

# -- names: one table for Unicode and LaTeX -------------------------------------

SUBSCRIPT = {"i": "\u1d62", "j": "\u2c7c", "k": "\u2096", "0": "\u2080", "1": "\u2081", "2": "\u2082"}
_COORD = re.compile(r"(x|y|phi)(d?)_(\w+)\Z")
_LOCAL = re.compile(r"([sv])([ijk])([xy])\Z")  # body-frame components: six, vjy
_ABBREV = re.compile(r"_([sad]|dd)_([ijk]?)([xy])\Z")  # display-only: s_i, a_i, d, d-dot
_FIXED = {"theta0": ("\u03b8\u2080", r"\theta_{0}"), "lambda": ("\u03bb", r"\lambda"),
          "lambda1": ("\u03bb\u2081", r"\lambda_{1}"), "lambda2": ("\u03bb\u2082", r"\lambda_{2}"),
          "f": ("f(t)", "f(t)"), "fd": ("f\u2032(t)", "f'(t)"), "fdd": ("f\u2033(t)", "f''(t)"),
          "fddd": ("f\u2034(t)", "f'''(t)"), "alpha": ("\u03b1", r"\alpha")}
_DOT = "\u0307"


def _tex_word(word: str) -> str:
    return word if len(word) == 1 else r"\mathrm{" + word.replace("_", r"\_") + "}"


def display_names(name: str) -> tuple[str, str] | None:
    """(Unicode, LaTeX) of a symbol of the symbol table, None for other names."""
    if name in _FIXED:
        return _FIXED[name]
    if m := _COORD.match(name):
        base, dot, who = m.groups()
        uni = ("\u03c6" if base == "phi" else base) + (_DOT if dot else "")
        uni += SUBSCRIPT[who] if who in "ijk" and len(who) == 1 else "_" + who
        tex = (r"\phi" if base == "phi" else base)
        return uni, (r"\dot{" + tex + "}" if dot else tex) + "_{" + _tex_word(who) + "}"
    if m := _LOCAL.match(name):
        base, role, comp = m.groups()
        return f"{base}\u2032{SUBSCRIPT[role]}{comp}", f"{base}'_{{{role}{comp}}}"
    if m := _ABBREV.match(name):
        base, role, comp = m.groups()
        uni = ("d" + _DOT if base == "dd" else base) + (SUBSCRIPT[role] if role else "") + comp
        return uni, (r"\dot{d}" if base == "dd" else base) + f"_{{{role}{comp}}}"
    return None


class Pretty(PrettyPrinter):
    def _print_Symbol(self, e: sp.Symbol, bold_name: bool = False) -> prettyForm:
        names = display_names(e.name)
        return prettyForm(names[0]) if names else super()._print_Symbol(e, bold_name)


class Latex(LatexPrinter):
    def _print_Symbol(self, e: sp.Symbol, style: str = "plain") -> str:
        names = display_names(e.name)
        return names[1] if names else super()._print_Symbol(e, style)


def pretty(expr: sp.Basic) -> str:
    """Unicode of an expression in the notation of docs/symbols.md."""
    return Pretty({"use_unicode": True, "wrap_line": False}).doprint(scalar(expr))


def latex(expr: sp.Basic) -> str:
    """LaTeX of an expression in the notation of docs/symbols.md."""
    return Latex().doprint(scalar(expr))


def scalar(expr: sp.Basic) -> sp.Basic:
    return expr[0] if isinstance(expr, sp.MatrixBase) and expr.shape == (1, 1) else expr
