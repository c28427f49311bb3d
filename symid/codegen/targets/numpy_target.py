"""The NumPy target: one standalone module per mechanism, importing only numpy.

Each quantity is printed twice from one CSE: vectorized over instants (numpy
ufuncs) and for one instant (`math` on floats, what a Newton loop calls),
and the sparse elimination fixed at generation time is printed as
straight-line Python for the one-instant solver.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter

from symid.codegen.emit import lu_steps, reduce
from symid.codegen.model import CodeModel
from symid.codegen.render import render
from symid.io.files import atomic_write
from symid.codegen.sparse import REFINE_SPREAD, THRESHOLD
from symid.numeric.newton import RULE
from symid.model.motion import piece_tables, tables

NAME = "numpy"


EXACT = 2**53  # integers below it are doubles exactly: Python's int/int rounds them correctly


def _literal(x: float) -> str:
    """A Python literal of the double x ('inf' and 'nan' are no literals)."""
    if math.isfinite(x):
        return repr(x)
    return "float('nan')" if math.isnan(x) else "float('inf')" if x > 0 else "(-float('inf'))"


def _quotient(p: int, q: int) -> float:
    """p / q correctly rounded to a double, +-inf beyond the range."""
    try:
        return p / q
    except OverflowError:
        return math.inf if p > 0 else -math.inf


class _Printing:
    """What both printers print alike: every float at full precision, a
    group in parentheses, a table's spline by `SPLINE` of the module.

    A constant past the doubles (a mass of 1e308 times g, folded by sympy into
    one integer) is printed as the double it rounds to, inf beyond the range,
    as the C printer does: an integer literal that large made the module raise
    OverflowError (int too large to convert to float) instead of the run
    stopping at the instant, naming the body whose values are not finite."""

    SPLINE = ""

    def _print_Float(self, expr: sp.Float) -> str:
        return _literal(float(expr))

    def _print_Integer(self, expr: sp.Integer) -> str:
        n = int(expr)
        return str(n) if abs(n) < EXACT else _literal(_quotient(n, 1))

    def _print_Rational(self, expr: sp.Rational) -> str:
        p, q = int(expr.p), int(expr.q)
        if abs(p) < EXACT and q < EXACT:
            return super()._print_Rational(expr)  # type: ignore[misc]
        return _literal(_quotient(p, q))

    def _print_Grouped(self, expr: sp.Expr) -> str:
        return f"({self._print(expr.args[0])})"  # type: ignore[attr-defined]

    def _print_TableSpline(self, expr: sp.Expr) -> str:
        key, order, x = expr.args
        return f"{self.SPLINE}(_TABLE_{key.name}, {self._print(x)}, {int(order)})"  # type: ignore[attr-defined]


class Printer(_Printing, NumPyPrinter):
    """NumPy printing with every float at full precision."""

    SPLINE = "_spline"


class ScalarPrinter(_Printing, PythonCodePrinter):
    """`math` printing for one instant, floats at full precision."""

    SPLINE = "_spline_s"


_PRINTER = Printer({"fully_qualified_modules": True})
_SCALAR = ScalarPrinter({"fully_qualified_modules": True})


def pycode(expr: sp.Expr) -> str:
    return _PRINTER.doprint(expr)


def mathcode(expr: sp.Expr) -> str:
    return _SCALAR.doprint(expr)


def _function(name: str, args: list[str], exprs: list[sp.Expr], doc: str) -> dict[str, Any]:
    chunks = reduce(exprs)
    return {"name": name, "args": args, "doc": doc, "size": len(exprs),
            "vector": [c.printed(pycode) for c in chunks], "scalar": [c.printed(mathcode) for c in chunks],
            "like": "q[0]" if "q" in args else "0.0"}


def _lu(model: CodeModel) -> dict[str, Any]:
    plan = model.plan
    steps = lu_steps(plan)
    return {"steps": steps, "lu_size": plan.size, "singular_plan": plan.singular,
            "pivot_rows": [st["row"] for st in steps], "pivot_cols": [st["col"] for st in steps]}


def _row_items(model: CodeModel) -> str:
    """The starred parts of one `rows` row after t: each group in contract order."""
    o = model.flat.options
    parts = {"q": "qn", "qdot": "qdn" if o.velocity else None, "qddot": "qddn" if o.velocity else None,
             "lambda": "lam" if o.multipliers else None, "reactions": "reac" if o.multipliers else None}
    return ", ".join(f"*{parts[g] or '_ZEROS'}" for g in o.outputs)


def _finite_sum(model: CodeModel) -> str:
    """The sum of everything an instant computes (q and, as compiled, qd, qdd,
    lambda, reactions): finite exactly when they all are, barring overflow."""
    o = model.flat.options
    parts = ["qn"] + (["qdn", "qddn"] if o.velocity else []) + (["lam"] if o.multipliers else [])
    parts += ["reac"] if o.multipliers and model.flat.reactions else []
    return " + ".join(f"sum({v})" for v in parts)


def context(model: CodeModel) -> dict[str, Any]:
    f = model.flat
    o = f.options
    functions = [
        _function("phi", ["q", "t", "p"], f.phi, "Phi, size NC."),
        _function("phi_q_values", ["q", "t", "p"], [e for _, _, e in f.jac],
                  "The stored values of Phi_q (rows PHI_Q_ROWS, columns PHI_Q_COLS)."),
    ]
    if o.velocity:
        functions += [_function("nu", ["q", "t", "p"], f.nu, "nu = -Phi_t, size NC."),
                      _function("gamma", ["q", "qd", "t", "p"], f.gamma, "gamma, size NC.")]
    if o.multipliers:
        functions += [_function("applied", ["q", "qd", "t", "p"], f.applied, "Q^A, size NG."),
                      _function("mass", ["p"], f.mass, "The diagonal of M, size NG.")]
    if f.reactions:
        functions.append(_function("reactions", ["q", "lam", "t", "p"], f.reactions,
                                   "Fx, Fy, T per body role of each requested constraint, size NR."))
    return {
        "name": f.name, "ng": f.ng, "nc": f.nc, "np_": len(f.params), "nr": len(f.reactions),
        "params": f.params, "derived": f.derived, "defaults": [repr(float(v)) for v in f.defaults],
        "jac_rows": [r for r, _, _ in f.jac], "jac_cols": [c for _, c, _ in f.jac], "nnz": len(f.jac),
        "functions": functions, "outputs": o.outputs, "kind": o.kind, "threshold": repr(THRESHOLD), "refine_spread": repr(REFINE_SPREAD),
        "velocity": o.velocity, "multipliers": o.multipliers, **_lu(model), "row_items": _row_items(model),
        "finite_sum": _finite_sum(model),
        "max_newton": RULE.max_iterations, "floor_ulps": repr(RULE.floor_ulps),
        "phi_q_scalar": functions[1]["scalar"],
        "splines": [piece_tables(s) for s in tables(f.phi + f.nu + f.gamma + f.applied + f.reactions)],
    }


def generate(model: CodeModel, out_dir: Path) -> list[Path]:
    """Write `<name>_solver.py` into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{model.name}_solver.py"
    text = render("numpy/module.py.j2", **context(model))
    with atomic_write(path) as out:  # whole or not at all, a fault named in one line (disk full)
        out.write(text)
    return [path]
