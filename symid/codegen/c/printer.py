"""C expressions for one scalar type: the printer of the C target and its
literals (double, or float with the f suffix and sinf/cosf/sqrtf)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import sympy as sp
from sympy.codegen.ast import float32, real
from sympy.printing.c import C99CodePrinter


@dataclass(frozen=True)
class Scalar:
    """One C floating type: its name, the suffix of its literals and of its
    libm functions, and the epsilon the rounding floor scales.

    Attributes:
        ctype: "double" or "float".
        suffix: "" or "f" (literals 1.5f, functions sinf).
        eps: the C expression of the type's machine epsilon.
        exact: integers below this are values of the type exactly.
    """

    ctype: str
    suffix: str
    eps: str
    exact: int

    def lit(self, x: float) -> str:
        """A literal of exactly x rounded to the type (+-INFINITY, NAN from <math.h>, of the type)."""
        if math.isnan(x):  # <math.h>'s NAN and INFINITY are floats: cast, not promoted (-Wdouble-promotion)
            return f"(({self.ctype})NAN)" if not self.suffix else "NAN"
        if self.suffix and abs(x) > float(np.finfo(np.float32).max):  # past the float range
            x = math.copysign(math.inf, x)
        if math.isinf(x):
            inf = f"(({self.ctype})INFINITY)" if not self.suffix else "INFINITY"
            return inf if x > 0 else f"(-{inf})"
        if not self.suffix:
            return repr(x)  # shortest round-trip digits, always with '.' or an exponent
        text = str(np.float32(x))  # the shortest digits of the nearest float
        return (text if "." in text or "e" in text else text + ".0") + "f"

    def fn(self, name: str) -> str:
        """The libm function of this type (sin -> sinf)."""
        return name + self.suffix

    def relit(self, line: str) -> str:
        """A line printed with double literals (repr) and libm calls, in this
        type: every floating literal rounded to it, fabs -> fabsf."""
        if not self.suffix:
            return line
        line = _LITERAL.sub(lambda m: self.lit(float(m.group(0))), line)
        return re.sub(r"\b(fabs|fmax|fmin|sqrt|sin|cos)\(", lambda m: self.fn(m.group(1)) + "(", line)


_LITERAL = re.compile(r"(?<![\w.\[])(?:\d+\.\d*(?:e[-+]?\d+)?|\d+e[-+]?\d+)(?![\w.])")

DOUBLE = Scalar("double", "", "2.220446049250313e-16", 2**53)
SINGLE = Scalar("float", "f", "1.1920929e-07f", 2**24)
PRECISIONS = {"double": DOUBLE, "single": SINGLE}

# |integer exponents| up to this are printed as products: x*x (what pow(x, 2)
# costs under -ffreestanding, where the compiler does not fold it, is a call)
MAX_PRODUCT = 8


class Printer(C99CodePrinter):
    """C99 without the POSIX constants (M_PI is not in strict C99), literals
    and libm calls of one scalar type, integer powers as products and
    half-integer ones through sqrt; a tabled function calls the generated
    `<prefix>_spline_<key>(t, order)`."""

    _default_settings = {**C99CodePrinter._default_settings, "prefix": "symid", "scalar": DOUBLE}

    def __init__(self, settings: dict | None = None) -> None:  # type: ignore[type-arg]
        settings = dict(settings or {})
        if settings.get("scalar", DOUBLE).suffix:
            settings["type_aliases"] = {real: float32}
        super().__init__(settings)

    @property
    def scalar(self) -> Scalar:
        return self._settings["scalar"]  # type: ignore[no-any-return]

    def _print_Add(self, expr: sp.Add, order: str | None = None) -> str:
        # a product or quotient among the terms in parentheses: the precedence
        # explicit (MISRA C:2012 rule 12.1), the grouping C parses anyway
        text = super()._print_Add(expr, order=order)
        return " ".join(f"({t})" if _loose(t) else t for t in _terms(text))

    def _print_TableSpline(self, expr: sp.Expr) -> str:
        key, order, x = expr.args
        return f"{self._settings['prefix']}_spline_{key.name}({self._print(x)}, {int(order)})"

    def _print_Wrap(self, expr: sp.Expr) -> str:
        return f"{self._settings['prefix']}_wrap({self._print(expr.args[0])})"

    def _print_Grouped(self, expr: sp.Expr) -> str:
        return f"({self._print(expr.args[0])})"

    def _print_sign(self, expr: sp.Expr) -> str:
        # the comparison difference is an int: say it becomes the scalar type (float: -Wconversion)
        x = self._print(expr.args[0])
        return f"(({self.scalar.ctype})((({x}) > 0) - (({x}) < 0)))"

    def _print_Pi(self, expr: sp.Expr) -> str:
        return self.scalar.lit(float(sp.pi))

    def _print_Exp1(self, expr: sp.Expr) -> str:
        return self.scalar.lit(float(sp.E))

    def _print_Float(self, expr: sp.Float) -> str:
        return self.scalar.lit(float(expr))

    def _print_Integer(self, expr: sp.Integer) -> str:
        # an integer literal past 2^63 does not compile; past `exact` it is not a value of the type
        n = int(expr)  # a floating literal: every value printed is of the real type (MISRA C:2012 10.3, 10.4)
        return self.scalar.lit(float(n)) if abs(n) < self.scalar.exact else self.scalar.lit(_quotient(n, 1))

    def _print_Rational(self, expr: sp.Rational) -> str:
        p, q = int(expr.p), int(expr.q)
        if abs(p) < self.scalar.exact and q < self.scalar.exact:  # both exact: C divides them, correctly rounded
            s = self.scalar.suffix
            return f"{p}.0{s}/{q}.0{s}"
        return self.scalar.lit(_quotient(p, q))

    def _print_Pow(self, expr: sp.Pow) -> str:
        base, exp = expr.args
        one = self.scalar.lit(1.0)
        b = self.parenthesize(base, 60) if not base.is_Atom else self._print(base)
        # repeating a base without calls costs nothing (the compiler shares it);
        # one with calls goes through <prefix>_powi, a product loop, once
        simple = not any(f.func.__name__ != "Grouped" for f in base.atoms(sp.Function))
        if exp.is_Integer and 1 < abs(int(exp)) <= MAX_PRODUCT:
            n = abs(int(exp))
            product = "*".join([b] * n) if base.is_Atom or simple else \
                f"{self._settings['prefix']}_powi({self._print(base)}, {n})"
            return f"({product})" if exp > 0 else f"({one}/({product}))"
        if exp == -1:
            return f"({one}/{b})"
        if exp == sp.Rational(1, 2):
            return f"{self.scalar.fn('sqrt')}({self._print(base)})"
        if exp == -sp.Rational(1, 2):
            return f"({one}/{self.scalar.fn('sqrt')}({self._print(base)}))"
        if exp.is_Rational and exp.q == 2 and 1 < abs(exp.p) <= 2 * MAX_PRODUCT + 1 and (base.is_Atom or simple):
            whole = "*".join([b] * ((abs(exp.p) - 1) // 2)) if abs(exp.p) > 1 else b
            root = f"{self.scalar.fn('sqrt')}({self._print(base)})"
            return f"({whole}*{root})" if exp > 0 else f"({one}/({whole}*{root}))"
        return super()._print_Pow(expr)  # type: ignore[no-any-return]


def _terms(text: str) -> list[str]:
    """The words of a printed sum split at its top-level ' + ' / ' - ' (kept
    as words of their own)."""
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += ch in "(["
        depth -= ch in ")]"
        if depth == 0 and text.startswith((" + ", " - "), i):
            out += [text[start:i], text[i + 1]]
            start = i + 3
    return out + [text[start:]]


def _loose(term: str) -> bool:
    """Whether a printed term has a top-level * or / (outside brackets)."""
    depth = 0
    for ch in term:
        depth += ch in "(["
        depth -= ch in ")]"
        if depth == 0 and ch in "*/":
            return True
    return False


def _quotient(p: int, q: int) -> float:
    """p / q correctly rounded to a double, +-inf beyond the range."""
    try:
        return p / q
    except OverflowError:
        return math.inf if p > 0 else -math.inf


def c_double(x: float) -> str:
    """A C99 double literal of exactly x (subnormals included; +-INFINITY, NAN from <math.h>)."""
    return DOUBLE.lit(x)


def printer(prefix: str, scalar: Scalar = DOUBLE) -> Printer:
    return Printer({"math_macros": {}, "prefix": prefix, "scalar": scalar})
