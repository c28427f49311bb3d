"""Motion laws and tabled functions of time, as sympy expressions.

Both kinds are ordinary sympy expressions, so the shared derivation
differentiates them for nu (f') and gamma (f'') unchanged:

- motion laws (`cycloidal`, `harmonic`, `poly345`, `rise_dwell_return`) are
  `Piecewise` formulas: dwell, rise, dwell; their derivatives are exact;
- a table (`symid.io.table` reads and fits it) is `TableSpline(key, order, x)`:
  the order-th derivative of a C2 cubic spline at x. `key` is a hash of the
  spline's knots and coefficients, so the printed expression (and every cache
  key built from it) changes when the data does. The numbers are kept in a
  registry keyed by that hash (filled when a table is read, and again when
  an expression is unpickled): content-addressed, so no order of calls matters.

See docs/motion.md for the formulas and the table rules.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Iterable

import numpy as np
import sympy as sp
from sympy.core.function import ArgumentIndexError
from sympy.core.symbol import Str

from symid.errors import InputError
from symid.model.expr import Functions
from symid.model.mechanism import Mechanism

# -- motion laws ---------------------------------------------------------


def _rise(x: sp.Expr, x0: sp.Expr, T: sp.Expr, h: sp.Expr, shape: sp.Expr, u: sp.Symbol) -> sp.Expr:
    """0 before x0, h * shape(u) with u = (x - x0)/T on [x0, x0 + T), h after."""
    if T.is_number and not T.is_positive:
        raise ValueError(f"the duration T must be positive, not {T}")
    return sp.Piecewise((sp.Integer(0), x < x0), (h * shape.xreplace({u: (x - x0) / T}), x < x0 + T),
                        (h, True))


_U = sp.Symbol("u", real=True)
_SHAPES = {
    # s(u) on [0, 1], s(0) = 0, s(1) = 1, s'(0) = s'(1) = 0
    "cycloidal": _U - sp.sin(2 * sp.pi * _U) / (2 * sp.pi),  # s'' = 0 at both ends: C2
    "harmonic": (1 - sp.cos(sp.pi * _U)) / 2,  # s'' = +-pi^2/2 at the ends: C1 only
    "poly345": 10 * _U**3 - 15 * _U**4 + 6 * _U**5,  # s'' = 0 at both ends: C2
}


def cycloidal(x: sp.Expr, x0: sp.Expr, T: sp.Expr, h: sp.Expr) -> sp.Expr:
    """Cycloidal rise by h over [x0, x0 + T]: h (u - sin(2 pi u) / (2 pi))."""
    return _rise(x, x0, T, h, _SHAPES["cycloidal"], _U)


def harmonic(x: sp.Expr, x0: sp.Expr, T: sp.Expr, h: sp.Expr) -> sp.Expr:
    """Simple harmonic rise by h over [x0, x0 + T]: h (1 - cos(pi u)) / 2."""
    return _rise(x, x0, T, h, _SHAPES["harmonic"], _U)


def poly345(x: sp.Expr, x0: sp.Expr, T: sp.Expr, h: sp.Expr) -> sp.Expr:
    """3-4-5 polynomial rise by h over [x0, x0 + T]: h (10 u^3 - 15 u^4 + 6 u^5)."""
    return _rise(x, x0, T, h, _SHAPES["poly345"], _U)


def rise_dwell_return(x: sp.Expr, x0: sp.Expr, T_rise: sp.Expr, T_dwell: sp.Expr, T_return: sp.Expr,
                      h: sp.Expr) -> sp.Expr:
    """3-4-5 rise by h over T_rise from x0, dwell T_dwell, 3-4-5 return to 0 over T_return."""
    if T_dwell.is_number and T_dwell.is_negative:
        raise ValueError(f"the dwell T_dwell must not be negative, not {T_dwell}")
    return poly345(x, x0, T_rise, h) - poly345(x, x0 + T_rise + T_dwell, T_return, h)


# name -> (arity, builder), for `symid.model.expr.parse_expression(functions=...)`
LAWS: Functions = MappingProxyType({
    "cycloidal": (4, cycloidal), "harmonic": (4, harmonic), "poly345": (4, poly345),
    "rise_dwell_return": (6, rise_dwell_return),
})

# -- tabled functions ------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Spline:
    """A C2 piecewise cubic on [knots[0], knots[-1]].

    Attributes:
        knots: breakpoints, strictly increasing, shape (n + 1,).
        coef: per piece k, [c0, c1, c2, c3] of c0 + c1 s + c2 s^2 + c3 s^3 with
            s = x - knots[k], shape (n, 4).
        label: where it came from ("motion.csv, column 'angle'"), for messages.
    """

    knots: np.ndarray
    coef: np.ndarray
    label: str

    @property
    def key(self) -> str:
        h = hashlib.sha256(np.ascontiguousarray(self.knots, "<f8").tobytes())
        h.update(np.ascontiguousarray(self.coef, "<f8").tobytes())
        return "s" + h.hexdigest()[:16]

    @property
    def span(self) -> tuple[float, float]:
        return float(self.knots[0]), float(self.knots[-1])

    @property
    def bounds(self) -> tuple[float, float]:
        """The span widened by a few rounding errors of a time: t0 + k (t1 - t0)/(steps - 1)
        may land an ulp past t1. Outside these, every backend gives NaN."""
        lo, hi = self.span
        slack = 16 * float(np.finfo(float).eps) * max(abs(lo), abs(hi), hi - lo)
        return lo - slack, hi + slack

    def __call__(self, x: Any, order: int = 0) -> np.ndarray:
        """The order-th derivative at x (any shape); NaN outside `bounds`."""
        x = np.asarray(x, dtype=float)
        n = len(self.coef)
        k = np.clip(np.searchsorted(self.knots, x, side="right") - 1, 0, n - 1)
        s = x - self.knots[k]
        c0, c1, c2, c3 = (self.coef[k, j] for j in range(4))
        if order == 0:
            v = ((c3 * s + c2) * s + c1) * s + c0
        elif order == 1:
            v = (3.0 * c3 * s + 2.0 * c2) * s + c1
        elif order == 2:
            v = 6.0 * c3 * s + 2.0 * c2
        elif order == 3:
            v = 6.0 * c3
        else:
            v = np.zeros_like(s)
        lo, hi = self.bounds
        return np.where((x >= lo) & (x <= hi), v, np.nan)


_SPLINES: dict[str, Spline] = {}


def _restore(name: str, knots: np.ndarray, coef: np.ndarray, label: str) -> "TableKey":
    register(Spline(knots, coef, label))
    return TableKey(name)


class TableKey(Str):
    """The name of a registered spline, printed as a string literal in Python
    code (so `lambdify` passes it to `TableSpline._imp_`)."""

    def _numpycode(self, printer: Any) -> str:
        return repr(self.name)

    _pythoncode = _numpycode

    def __reduce_ex__(self, protocol: Any) -> Any:
        s = spline(self.name)
        return _restore, (self.name, s.knots, s.coef, s.label)


def spline(key: str) -> Spline:
    """The registered spline of a key."""
    return _SPLINES[key]


def _evaluate(key: str, order: Any, x: Any) -> Any:
    out = spline(key)(x, int(order))
    return float(out) if out.ndim == 0 else out


class TableSpline(sp.Function):
    """TableSpline(key, order, x): d^order/dx^order of the registered spline `key` at x."""

    nargs = 3
    is_real = True
    _imp_ = staticmethod(_evaluate)  # what lambdify calls

    @classmethod
    def eval(cls, key: Any, order: Any, x: Any) -> None:
        return None

    @property
    def spline(self) -> Spline:
        return spline(self.args[0].name)

    @property
    def order(self) -> int:
        return int(self.args[1])

    def fdiff(self, argindex: int = 3) -> sp.Expr:
        if argindex != 3:
            raise ArgumentIndexError(self, argindex)
        key, order, x = self.args
        return TableSpline(key, order + 1, x)

    def _eval_derivative(self, s: sp.Symbol) -> sp.Expr:
        # sympy's default would differentiate the key too, which is no expression
        key, order, x = self.args
        return TableSpline(key, order + 1, x) * sp.diff(x, s)

    def _eval_evalf(self, prec: int) -> sp.Expr | None:
        x = self.args[2].evalf(prec)
        return sp.Float(_evaluate(self.args[0].name, self.order, float(x)), prec) if x.is_Number else None

    def _latex(self, printer: Any) -> str:
        primes = "'" * self.order if self.order <= 3 else f"^{{({self.order})}}"
        return rf"\mathrm{{table}}_{{{self.args[0].name[:7]}}}{primes}\left({printer._print(self.args[2])}\right)"


def register(s: Spline) -> sp.Expr:
    """Keep a spline and return it as a function of t: TableSpline(key, 0, t)."""
    from symid.model.mechanism import T

    key = s.key
    _SPLINES.setdefault(key, s)
    return TableSpline(TableKey(key), sp.Integer(0), T)


def tables(exprs: Iterable[sp.Expr]) -> list[Spline]:
    """The distinct splines used in some expressions, in key order (deterministic code)."""
    keys = {a.args[0].name for e in exprs for a in sp.sympify(e).atoms(TableSpline)}
    return [spline(k) for k in sorted(keys)]


def check_spans(mech: Mechanism) -> None:
    """Refuse an analysis that runs outside the span of a table it uses: a
    spline is never extrapolated. Raises InputError naming the element, key and span."""
    a = mech.analysis
    t1 = a.t0 if a.steps == 1 else a.t1
    for section, elements in (("constraint", mech.constraints), ("force", mech.forces)):
        for el in elements:
            for key, value in el.values.items():
                for s in tables(value if isinstance(value, tuple) else (value,)):
                    lo, hi = s.span
                    if not (lo <= a.t0 and t1 <= hi):
                        raise InputError(
                            f"{mech.source}: {section} '{el.name}' key '{key}': the analysis runs over "
                            f"t = [{float(a.t0)!r}, {float(t1)!r}], outside the span [{lo!r}, {hi!r}] of "
                            f"{s.label} (a table is not extrapolated: set t0, t1 inside it)")


def piece_tables(s: Spline) -> dict[str, Any]:
    """A spline's numbers printed for generated code (shortest round-trip decimals)."""
    lo, hi = s.bounds
    return {"key": s.key, "n": len(s.coef), "knots": [repr(float(v)) for v in s.knots],
            "coef": [repr(float(v)) for v in s.coef.reshape(-1)], "lo": repr(lo), "hi": repr(hi),
            "span": f"[{s.span[0]!r}, {s.span[1]!r}]"}

