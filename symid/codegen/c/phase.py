"""Small phases for single precision: time and angles kept exact enough for long runs.

In float, t = 1e4 s has an ulp of 1e-3 s and omega t = 3e5 rad one of
3e-2 rad, so sin(omega t), a driven crank angle and every output that reads
them lose all their digits long before the run ends. This module rewrites
a mechanism's expressions so that the generated single-precision code only
ever sees small numbers:

- each term linear in time, a t with a free of t (inside sin/cos, or in a
  row that compares angles), becomes a *phase* symbol: 2 pi frac(nu t),
  nu = a / (2 pi) (turns per second, computed in double from p once per
  call by prepare, kept as two floats) and frac the signed fraction, in
  [-pi, pi]. It is computed from t = t0 + k h (k the step count) with
  error-free products, so it is exact to ~1e-7 rad at any t;
- a constraint row whose angles enter only with integer coefficients
  outside sin/cos (relative angle and coordinate drivers on phi, the
  translational joint's theta0 row) is 2 pi-periodic in them: its residual
  is reduced modulo 2 pi (`Wrap`), so it can compare a wrapped angle with a
  wrapped phase;
- an angle coordinate read only through sin/cos and such rows is reduced by
  whole turns when it leaves [-4 pi, 4 pi] (`wrap_angles`): a crank turning
  for hours keeps an ulp of 1e-6 rad; a motion within two turns either way
  is left as it is.

What is not reducible (t^2, a motion law's rise, a table, a gear ratio
between angles) keeps t or the angle as it is: the long-run bound does not
apply there, and the header says so. Double precision is not rewritten.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Collection, Sequence

import numpy as np
import sympy as sp

from symid.codegen.c.printer import SINGLE, printer
from symid.model.mechanism import T
from symid.model.motion import TableSpline
from symid.symbolic.rounding import Grouped


class Wrap(sp.Function):
    """Wrap(x): x reduced modulo 2 pi into [-pi, pi] (printed as `<prefix>_wrap(x)`)."""

    nargs = 1
    is_real = True

    @classmethod
    def eval(cls, arg: Any) -> None:
        return None


def _plain(e: sp.Expr) -> sp.Expr:
    """e without its Grouped wrappers (the value, for analysis)."""
    return e.replace(Grouped, lambda x: x) if e.has(Grouped) else e


def _angles(ng: int) -> list[sp.Symbol]:
    return [sp.Symbol(f"q[{3 * b + 2}]", real=True) for b in range(ng // 3)]


def _coordinates(e: sp.Expr) -> set[sp.Symbol]:
    return {s for s in e.free_symbols if s.name.startswith(("q[", "qd["))}


def _outside_trig(e: sp.Expr) -> set[sp.Symbol]:
    """The symbols of e read other than through sin or cos."""
    e = e.replace(lambda x: isinstance(x, (sp.sin, sp.cos)), lambda x: sp.Dummy())
    return e.free_symbols


@dataclass
class Phases:
    """The phases found so far: nu[j] (turns per second, an expression of
    the parameters) is printed as the symbol ph[j] until `place` renames it."""

    nu: list[sp.Expr] = field(default_factory=list)
    symbols: list[sp.Symbol] = field(default_factory=list)

    def of(self, a: sp.Expr) -> sp.Expr:
        """The phase of a t (a free of t) modulo 2 pi: +-ph[j]."""
        nu = sp.factor_terms(a / (2 * sp.pi))
        sign = 1
        if nu.could_extract_minus_sign():
            nu, sign = -nu, -1
        if nu not in self.nu:
            self.nu.append(nu)
            self.symbols.append(sp.Symbol(f"ph[{len(self.nu) - 1}]", real=True))
        return sign * self.symbols[self.nu.index(nu)]

    def linear(self, u: sp.Expr) -> tuple[sp.Expr, sp.Expr] | None:
        """(a, b) with u = a t + b, a and b free of t (and a of the coordinates), or None."""
        if not u.has(T):
            return None
        a = sp.diff(u, T)
        if a.has(T) or _coordinates(a) or a == 0:
            return None
        b = sp.expand(u - a * T)
        return None if b.has(T) else (a, b)

    def trig(self, e: sp.Expr) -> sp.Expr:
        """e with every sin/cos of an argument linear in t read from its phase."""
        def swap(f: sp.Expr) -> sp.Expr:
            lin = self.linear(_plain(f.args[0]))
            return f if lin is None else f.func(self.of(lin[0]) + lin[1])
        return e.replace(lambda x: isinstance(x, (sp.sin, sp.cos)) and x.args[0].has(T), swap)

    def row(self, e: sp.Expr, coefficients: dict[sp.Symbol, int]) -> sp.Expr:
        """A constraint row periodic in its angles (their integer
        coefficients), wrapped, its terms linear in t read from their phases."""
        u = _plain(e)
        rest = sp.expand(u - sum(c * a for a, c in coefficients.items()))
        terms = []
        for term in sp.Add.make_args(rest):
            lin = self.linear(term)
            terms.append(self.of(lin[0]) + lin[1] if lin is not None else term)
        return Wrap(sp.Add(*[c * a for a, c in sorted(coefficients.items(), key=lambda x: str(x[0]))])
                    + self.trig(sp.Add(*terms)))


def _periodic(e: sp.Expr, angles: set[sp.Symbol]) -> dict[sp.Symbol, int] | None:
    """The integer coefficients of the angles e reads other than through sin
    and cos, if e is 2 pi-periodic in them and reads no other coordinate so
    (an angle row: a relative angle, a driven phi); else None."""
    u = _plain(e)
    outside = _outside_trig(u) & angles
    if not outside:
        return None
    coefficients = {a: sp.diff(u, a) for a in outside}
    if not all(c.is_Integer for c in coefficients.values()):
        return None  # a gear ratio: not periodic
    rest = sp.expand(u - sum(c * a for a, c in coefficients.items()))
    if _outside_trig(rest) & _coordinates(rest):
        return None  # the row also reads a length: not an angle
    return {a: int(c) for a, c in coefficients.items()}


@dataclass(frozen=True)
class Reduced:
    """The rewritten expression lists and what the C code needs for them.

    Attributes:
        groups: the lists, in the order given (phase symbols still ph[j]).
        nu: per phase, its turns per second (parameters only).
        wrapped_rows: the constraint rows reduced modulo 2 pi.
        angles: indices in q of the angle coordinates reduced by whole turns.
        kept: what keeps absolute time or angles (for the header), e.g.
            ["t in exp(...)", "q[2] (read other than ...)"].
        labels: each nu with the parameters' names (for comments).
    """

    groups: list[list[sp.Expr]]
    nu: list[sp.Expr]
    wrapped_rows: list[int]
    angles: list[int]
    kept: list[str]
    labels: list[str] = field(default_factory=list)


def reduce(ng: int, phi: Sequence[sp.Expr], others: Sequence[Sequence[sp.Expr]],
           names: Sequence[str] = (), fixed: Collection[int] = ()) -> Reduced:
    """Rewrite phi (the constraint rows) and the other lists read at an
    instant (Phi_q, nu, gamma, forces, reactions, ...) with phases and wraps;
    names: the parameters' (p[k] is printed so in `kept`); fixed: rows
    printed from elsewhere as they are (c_loops' looped kernels), never wrapped."""
    ph = Phases()
    angles = set(_angles(ng))
    rows = {r: c for r, e in enumerate(phi) if r not in fixed and (c := _periodic(e, angles)) is not None}
    rest: list[list[sp.Expr]] = [[ph.trig(e) for e in g] for g in others]
    # an angle read outside sin/cos anywhere but in a wrapped row keeps its
    # turns, and a row reading such an angle is not wrapped (a whole turn of
    # it would change what else reads it: a spring's torque); to a fixed point
    while True:
        unwrappable = {a for g in rest for e in g for a in _outside_trig(e) & angles}
        unwrappable |= {a for r, e in enumerate(phi) if r not in rows for a in _outside_trig(_plain(e)) & angles}
        keep = {r: c for r, c in rows.items() if not set(c) & unwrappable}
        if keep == rows:
            break
        rows = keep
    groups = [[ph.row(e, rows[r]) if r in rows else ph.trig(e) for r, e in enumerate(phi)]] + rest
    wrapped = sorted(rows)
    named = {sp.Symbol(f"p[{k}]", real=True): sp.Symbol(n, real=True) for k, n in enumerate(names)}
    kept = sorted({f"t in {_short(_plain(e).xreplace(named))}" for g in groups for e in g if e.has(T)})
    if unwrappable:
        listed = ", ".join(str(a) for a in sorted(unwrappable, key=lambda s: int(str(s)[2:-1])))
        kept.append(f"the angles {listed} (read other than through sin, cos and whole turns: a gear ratio, "
                    "a spring)")
    reduced = sorted(int(str(a)[2:-1]) for a in angles - unwrappable)
    return Reduced(groups, ph.nu, wrapped, reduced, kept, [str(v.xreplace(named)) for v in ph.nu])


def _short(e: sp.Expr) -> str:
    """The first term of e that reads t, shortened, for a comment."""
    if any(x.has(T) for x in e.atoms(TableSpline)):
        return "a table"
    if any(x.has(T) for x in e.atoms(sp.Piecewise)):
        return "a motion law (Piecewise)"
    terms = [x for x in sp.preorder_traversal(e) if isinstance(x, sp.Expr) and x.has(T) and not x.is_Add and x != T]
    # a function of t (exp(...)) rather than the product it is in, else that product
    term = next((x for x in terms if not x.is_Mul), terms[0] if terms else T)
    text = str(term)
    return text if len(text) <= 60 else text[:57] + "..."


def place(groups: Sequence[Sequence[sp.Expr]], offset: int, count: int) -> list[list[sp.Expr]]:
    """The lists with ph[j] renamed p[offset + j]: the slot of the prepared
    parameters the phases function writes at each instant."""
    names = {sp.Symbol(f"ph[{j}]", real=True): sp.Symbol(f"p[{offset + j}]", real=True) for j in range(count)}
    return [[e.xreplace(names) for e in g] for g in groups]


def nu_lines(nu: Sequence[sp.Expr], np_: int, off_nu: int, printer: Callable[[sp.Expr], str]) -> list[str]:
    """The C statements of prepare that keep each nu as two floats (hi, lo),
    computed from the base parameters in float-float arithmetic (a pair of
    floats, ~48 bits: templates/c/phase.j2's ff_ functions), once per call:
    no double anywhere, so a single build needs no double helpers
    (__aeabi_ddiv ...) on a target without a double FPU. printer: the
    single-precision printer, for a piece outside + - * / and integer and
    half powers (a function of parameters), computed in float (lo = 0)."""
    lines: list[str] = []
    count = [0]

    def pair() -> str:
        count[0] += 1
        return f"ff{count[0] - 1}"

    def const(x: sp.Expr) -> str:
        v = sp.N(x, 40)
        h = np.float32(float(v))
        lo = np.float32(float(v - sp.Float(float(h), 40)))
        name = pair()
        lines.append(f"{name}[0] = {SINGLE.lit(float(h))}; {name}[1] = {SINGLE.lit(float(lo))};")
        return name

    def emit(e: sp.Expr) -> str:
        if not e.free_symbols:
            return const(e)
        if e.is_Symbol:
            name = pair()
            lines.append(f"{name}[0] = {e.name}; {name}[1] = 0.0f;")
            return name
        if e.is_Add or e.is_Mul:
            num = [a for a in e.args if not (e.is_Mul and a.is_Pow and a.exp.is_negative)]
            den = [a.base ** -a.exp for a in e.args if e.is_Mul and a.is_Pow and a.exp.is_negative]
            acc = emit(num[0]) if num else const(sp.Integer(1))
            for a in num[1:]:
                out = pair()
                lines.append(f"{{p}}_ff_{'add' if e.is_Add else 'mul'}({acc}, {emit(a)}, {out});")
                acc = out
            for a in den:
                out = pair()
                lines.append(f"{{p}}_ff_div({acc}, {emit(a)}, {out});")
                acc = out
            return acc
        if e.is_Pow and e.exp.is_Integer and int(e.exp) > 0:
            b = emit(e.base)
            acc = b
            for _ in range(int(e.exp) - 1):
                out = pair()
                lines.append(f"{{p}}_ff_mul({acc}, {b}, {out});")
                acc = out
            return acc
        if e.is_Pow and e.exp.is_Rational and e.exp < 0:
            out = pair()
            lines.append(f"{{p}}_ff_div({const(sp.Integer(1))}, {emit(e.base ** -e.exp)}, {out});")
            return out
        if e.is_Pow and e.exp == sp.Rational(1, 2):
            out = pair()
            lines.append(f"{{p}}_ff_sqrt({emit(e.base)}, {out});")
            return out
        name = pair()  # a function of parameters: float only
        lines.append(f"{name}[0] = {printer(e)}; {name}[1] = 0.0f;")
        return name

    for j, v in enumerate(nu):
        r = emit(_plain(v))
        lines.append(f"{{p}}_ff_norm({r}[0], {r}[1], &pp[{off_nu + 2 * j}]);")  # by index (MISRA C:2012 18.4)
    return [f"{{p}}_real ff{k}[2];" for k in range(count[0])] + lines  # one declaration a statement (12.3)


# Single precision against double over the mechanism file's run: each column
# within this fraction of its peak (docs/c-export.md, single precision; the
# header states it as <P>_SINGLE_BOUND and the tests read it from there).
# The float rounding (6e-8) magnified by the conditioning of the bundled
# mechanisms' multipliers stays below 1e-5; joint friction's smooth sign
# tanh(v / v_smooth) turns the rounding of a speed near reversal into up to
# 3 % of a joint's friction (v_smooth 1e-4: the bundled friction example).
SINGLE_BOUND = 1e-5
FRICTION_BOUND = 5e-2


def single_bound(friction: bool) -> float:
    """The bound of single precision against double the header states, of a
    mechanism with (or without) joint friction."""
    return FRICTION_BOUND if friction else SINGLE_BOUND


@dataclass(frozen=True)
class Phase:
    """What templates/c/phase.j2, phase.h.j2 and prepare.j2 need (double: empty).

    Attributes:
        phases: each phase's nu with the parameters' names (comments).
        off_nu, off_phase: where the prepared parameters hold the nu pairs
            and the phases.
        wraps: whether any row or angle is reduced by whole turns.
        wrap_angles: indices in q of the angles reduced so.
        nu_lines: prepare's statements computing the nu pairs.
        kept: what keeps absolute time or angles (the header says so).
        ff_ops: the float-float operations nu_lines call.
    """

    phases: list[str]
    off_nu: int
    off_phase: int
    wraps: bool
    wrap_angles: list[int]
    nu_lines: list[str]
    kept: list[str]
    ff_ops: list[str]


def context(red: Reduced | None, off_nu: int, np_: int) -> Phase:
    """What the templates need for the phases (nothing in double: red None)."""
    if red is None:
        return Phase([], off_nu, off_nu, False, [], [], [], [])
    lines = nu_lines(red.nu, np_, off_nu, printer("symid", SINGLE).doprint)
    return Phase(phases=red.labels, off_nu=off_nu, off_phase=off_nu + 2 * len(red.nu),
                 wraps=bool(red.wrapped_rows or red.angles), wrap_angles=red.angles, nu_lines=lines, kept=red.kept,
                 ff_ops=[op for op in ("add", "mul", "div", "sqrt") if any(f"_ff_{op}(" in x for x in lines)])
