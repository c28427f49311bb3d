"""The CasADi target: one `casadi.Function` per quantity, saved with `Function.save`.

The flat sympy lists are walked once into CasADi SX graphs (a memo keyed by
subexpression shares every repeated subtree), over the inputs `q`, `qd`,
`lam`, `t` and the parameter vector `p`, so one saved function serves every
parameter set. The same functions go through CasADi's own C code generator
(`casadi_c`).
"""

from __future__ import annotations

import json
import operator
import tempfile
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import casadi as ca
import sympy as sp

from symid.codegen.flat import Flat
from symid.codegen.model import CodeModel
from symid.codegen.render import render
from symid.errors import InputError
from symid.io.files import atomic_write
from symid.model.motion import Spline, TableSpline
from symid.symbolic.rounding import Grouped

NAME = "casadi"
# Newton steps unrolled in `<name>_instant`: from a warm start (the previous
# instant's Taylor prediction) Newton converges quadratically in 3-4; the rest
# only repeat the converged q. Its `residual` output says whether it did.
NEWTON_STEPS = 8
HEADER = "Do not edit: regenerate with `symid generate` instead."

_FUNCTIONS: dict[type, Callable[..., Any]] = {
    sp.sin: ca.sin, sp.cos: ca.cos, sp.tan: ca.tan,
    sp.asin: ca.asin, sp.acos: ca.acos, sp.atan: ca.atan, sp.atan2: ca.atan2,
    sp.sinh: ca.sinh, sp.cosh: ca.cosh, sp.tanh: ca.tanh,
    sp.asinh: ca.asinh, sp.acosh: ca.acosh, sp.atanh: ca.atanh,
    sp.exp: ca.exp, sp.log: ca.log, sp.Abs: ca.fabs, sp.sign: ca.sign,
    sp.floor: ca.floor, sp.ceiling: ca.ceil,
    Grouped: lambda x: x,  # its sum is built first: the grouping holds
}
_RELATIONS: dict[type, Callable[[ca.SX, ca.SX], ca.SX]] = {
    sp.StrictLessThan: operator.lt, sp.LessThan: operator.le, sp.StrictGreaterThan: operator.gt,
    sp.GreaterThan: operator.ge, sp.Eq: operator.eq, sp.Ne: operator.ne,
    sp.And: ca.logic_and, sp.Or: ca.logic_or,
}


class _ToSX:
    """sympy -> SX, each distinct subexpression converted once (so shared
    subtrees stay shared in the graph; `ca.cse` then merges the rest).

    Args:
        symbols: sympy symbol name (`q[3]`, `t`, `p[0]`) -> SX scalar.
    """

    def __init__(self, symbols: Mapping[str, ca.SX]) -> None:
        self.symbols = symbols
        self.memo: dict[sp.Basic, ca.SX] = {}
        self.pieces: dict[tuple[str, sp.Basic], ca.SX] = {}  # (table, x) -> [s, c0, c1, c2, c3]

    def __call__(self, e: sp.Basic) -> ca.SX:
        out = self.memo.get(e)
        if out is None:
            out = self.memo[e] = self._convert(e)
        return out

    def _convert(self, e: sp.Basic) -> ca.SX:
        if e.is_Symbol:
            return self.symbols[e.name]  # type: ignore[attr-defined]
        if e.is_Number or e.is_NumberSymbol:
            return ca.SX(float(e))  # type: ignore[arg-type]
        if e.is_Add:
            return _fold(operator.add, [self(a) for a in e.args])
        if e.is_Mul:
            return _fold(operator.mul, [self(a) for a in e.args])
        if e.is_Pow:
            base, exponent = e.args
            return _power(self(base), exponent, self)
        if type(e) in _FUNCTIONS:
            return _FUNCTIONS[type(e)](*[self(a) for a in e.args])
        if isinstance(e, (sp.Min, sp.Max)):
            pick = ca.fmin if isinstance(e, sp.Min) else ca.fmax
            return _fold(pick, [self(a) for a in e.args])
        if isinstance(e, sp.Piecewise):  # the first true condition's value (motion laws)
            out = ca.SX(float("nan"))
            for value, cond in reversed(e.args):
                out = self(value) if cond == sp.true else ca.if_else(self(cond), self(value), out)
            return out
        if type(e) in _RELATIONS:
            return _fold(_RELATIONS[type(e)], [self(a) for a in e.args])
        if isinstance(e, sp.Not):
            return ca.logic_not(self(e.args[0]))
        if isinstance(e, TableSpline):
            return self._spline(e)
        raise NotImplementedError(f"casadi target: no CasADi counterpart for {type(e).__name__} in {e}")

    def _spline(self, e: TableSpline) -> ca.SX:
        """The same cubic piece as the other backends (not `ca.interpolant`, which fits
        its own spline), found by a balanced tree of exact selections."""
        spline, order = e.spline, e.order
        x = self(e.args[2])
        piece = self.pieces.get((e.args[0].name, e.args[2]))
        if piece is None:
            piece = self.pieces[(e.args[0].name, e.args[2])] = _piece(spline, x)
        s, c0, c1, c2, c3 = (piece[k] for k in range(5))
        value = {0: ((c3 * s + c2) * s + c1) * s + c0, 1: (3.0 * c3 * s + 2.0 * c2) * s + c1,
                 2: 6.0 * c3 * s + 2.0 * c2, 3: 6.0 * c3}.get(order, ca.SX(0.0))
        lo, hi = spline.bounds
        return ca.if_else(ca.logic_and(x >= lo, x <= hi), value, ca.SX(float("nan")))


def _piece(spline: Spline, x: ca.SX) -> ca.SX:
    """[x - knot, c0, c1, c2, c3] of the piece holding x (bisection as the C code does:
    piece a with knots[a] <= x < knots[a + 1], the end pieces extended)."""
    rows = [ca.DM([0.0, *spline.coef[k]]) for k in range(len(spline.coef))]
    knots = spline.knots

    def select(a: int, b: int) -> tuple[ca.SX, ca.SX]:
        if b - a == 1:
            return ca.SX(rows[a]), ca.SX(knots[a])
        m = a + (b - a) // 2
        left, right = select(a, m), select(m, b)
        below = x < knots[m]
        return ca.if_else(below, left[0], right[0]), ca.if_else(below, left[1], right[1])

    coef, knot = select(0, len(rows))
    return ca.vertcat(x - knot, coef[1:])


def _fold(op: Callable[[ca.SX, ca.SX], ca.SX], items: Sequence[ca.SX]) -> ca.SX:
    """Left to right, as sympy orders the arguments, so the graph is reproducible."""
    out = items[0]
    for item in items[1:]:
        out = op(out, item)
    return out


def _power(base: ca.SX, exponent: sp.Basic, convert: _ToSX) -> ca.SX:
    """Integer powers and square roots by CasADi's own rewriting (sq, products,
    sqrt: exact or correctly rounded, unlike a general pow)."""
    if exponent.is_Integer:
        return base ** int(exponent)
    if exponent == sp.Rational(1, 2):
        return ca.sqrt(base)
    if exponent == sp.Rational(-1, 2):
        return 1 / ca.sqrt(base)
    return ca.power(base, convert(exponent))


def _column(convert: _ToSX, exprs: Sequence[sp.Expr]) -> ca.SX:
    """A dense column vector (structural zeros kept, so its size is fixed)."""
    return ca.densify(ca.vertcat(*[convert(e) for e in exprs])) if exprs else ca.SX(0, 1)


def _sparse_jacobian(convert: _ToSX, flat: Flat) -> ca.SX:
    """Phi_q with exactly the derived pattern; CasADi stores it column-major."""
    order = sorted(range(len(flat.jac)), key=lambda k: (flat.jac[k][1], flat.jac[k][0]))
    pattern = ca.Sparsity.triplet(flat.nc, flat.ng, [flat.jac[k][0] for k in order],
                                  [flat.jac[k][1] for k in order])
    return ca.SX(pattern, ca.vertcat(*[convert(flat.jac[k][2]) for k in order]))


def functions(flat: Flat, instant: bool = True) -> dict[str, ca.Function]:
    """The CasADi functions of one mechanism, keyed by quantity, in a fixed order.

    Function `<name>_<key>` with inputs (sizes): q (ng), qd (ng), lam (nc),
    t (1), p (np, in `flat.params` order). Only what `flat.options` needs is
    built, as in the C target; `instant` adds `<name>_instant`.
    """
    o = flat.options
    q, qd, lam = ca.SX.sym("q", flat.ng), ca.SX.sym("qd", flat.ng), ca.SX.sym("lam", flat.nc)
    t, p = ca.SX.sym("t"), ca.SX.sym("p", len(flat.params))
    symbols = {"t": t}
    for name, vec in (("q", q), ("qd", qd), ("lam", lam), ("p", p)):
        symbols.update({f"{name}[{k}]": vec[k] for k in range(vec.numel())})
    convert = _ToSX(symbols)

    def fn(key: str, inputs: list[tuple[str, ca.SX]], out: ca.SX) -> ca.Function:
        return ca.Function(f"{flat.name}_{key}", [v for _, v in inputs], [ca.cse(out)],
                           [n for n, _ in inputs], [key])

    cq, cqd, clam, ct, cp = ("q", q), ("qd", qd), ("lam", lam), ("t", t), ("p", p)
    out = {
        "phi": fn("phi", [cq, ct, cp], _column(convert, flat.phi)),
        "phi_q": fn("phi_q", [cq, ct, cp], _sparse_jacobian(convert, flat)),
    }
    if o.velocity:
        out["nu"] = fn("nu", [cq, ct, cp], _column(convert, flat.nu))
        out["gamma"] = fn("gamma", [cq, cqd, ct, cp], _column(convert, flat.gamma))
    if o.kind != "kinematics" and o.multipliers:
        out["applied"] = fn("applied", [cq, cqd, ct, cp], _column(convert, flat.applied))
        out["mass"] = fn("mass", [cp], _column(convert, flat.mass))
    if flat.reactions:
        out["reactions"] = fn("reactions", [cq, clam, ct, cp], _column(convert, flat.reactions))
    if instant:
        out["instant"] = _instant(flat, out)
    return out


def _instant(flat: Flat, f: Mapping[str, ca.Function]) -> ca.Function:
    """(q_guess, t, p) -> (q, [qd, qdd], [lam], [reactions], residual = max |Phi(q)|).

    NEWTON_STEPS unrolled Newton steps, then the rates and multipliers with
    the converged Phi_q. An MX graph calling the quantity functions, solved by
    CasADi's numeric sparse QR (`solve(..., "qr")`, which its C generator
    supports), so the code holds each quantity once, not NEWTON_STEPS copies.
    """
    o = flat.options
    q_guess, t, p = ca.MX.sym("q_guess", flat.ng), ca.MX.sym("t"), ca.MX.sym("p", len(flat.params))
    q = q_guess
    for _ in range(NEWTON_STEPS):
        q = q - ca.solve(f["phi_q"](q, t, p), f["phi"](q, t, p), "qr")
    jac = f["phi_q"](q, t, p)
    names, outs = ["q"], [q]
    qd = qdd = ca.MX.zeros(flat.ng)
    if o.velocity:
        qd = ca.solve(jac, f["nu"](q, t, p), "qr")
        qdd = ca.solve(jac, f["gamma"](q, qd, t, p), "qr")
        names += ["qd", "qdd"]
        outs += [qd, qdd]
    if "applied" in f:
        lam = ca.solve(jac.T, f["applied"](q, qd, t, p) - f["mass"](p) * qdd, "qr")
        names.append("lam")
        outs.append(lam)
        if "reactions" in f:
            names.append("reactions")
            outs.append(f["reactions"](q, lam, t, p))
    names.append("residual")
    outs.append(ca.norm_inf(f["phi"](q, t, p)))
    return ca.Function(f"{flat.name}_instant", [q_guess, t, p], outs, ["q_guess", "t", "p"], names)


def _describe(f: ca.Function) -> dict[str, Any]:
    def ports(n: int, name: Callable[[int], str], sparsity: Callable[[int], ca.Sparsity]) -> list[dict[str, Any]]:
        return [{"name": name(k), "rows": sparsity(k).size1(), "cols": sparsity(k).size2(),
                 "nnz": sparsity(k).nnz()} for k in range(n)]

    return {"name": f.name(), "file": f"{f.name()}.casadi",
            "inputs": ports(f.n_in(), f.name_in, f.sparsity_in),
            "outputs": ports(f.n_out(), f.name_out, f.sparsity_out)}


def manifest(flat: Flat, fns: Mapping[str, ca.Function]) -> dict[str, Any]:
    """What a user of the saved functions needs: sizes, parameter order, sparsity."""
    return {
        "generated": f"Generated by symid (target casadi, symid/codegen/targets/casadi_target.py) "
                     f"for mechanism '{flat.name}'. {HEADER}",
        "mechanism": flat.name,
        "kind": flat.options.kind, "outputs": list(flat.options.outputs),
        "reactions": list(flat.options.reactions),
        "sizes": {"ng": flat.ng, "nc": flat.nc, "np": len(flat.params), "nnz": len(flat.jac),
                  "nr": len(flat.reactions)},
        "parameters": [{"name": n, "default": float(v)} for n, v in zip(flat.params, flat.defaults)],
        "derived": [{"name": n, "definition": d} for n, d in flat.derived],
        "phi_q_rows": [r for r, _, _ in flat.jac], "phi_q_cols": [c for _, c, _ in flat.jac],
        "newton_steps": NEWTON_STEPS if "instant" in fns else 0,
        "functions": {key: _describe(f) for key, f in fns.items()},
    }


def write(flat: Flat, out_dir: Path, instant: bool = True) -> list[Path]:
    """Save every function (`<name>_<key>.casadi`), `manifest.json` and `README.txt`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    fns = functions(flat, instant)
    written = []
    for f in fns.values():
        # Function.save is deterministic (same graph, same bytes); the text holds
        # CasADi's serialization format version, never a time or a path
        # the bytes Function.save writes, but written by us: save() leaves a
        # truncated file without an error on a full disk
        serializer = ca.StringSerializer()
        serializer.pack(f)
        written.append(_write(out_dir / f"{f.name()}.casadi", serializer.encode().encode("latin-1")))
    info = manifest(flat, fns)
    written.append(_write(out_dir / "manifest.json", (json.dumps(info, indent=2) + "\n").encode()))
    readme = render("casadi/README.txt.j2", name=flat.name, info=info,
                    params=[(n, repr(float(v))) for n, v in zip(flat.params, flat.defaults)],
                    derived=flat.derived)
    written.append(_write(out_dir / "README.txt", readme.encode()))
    return written


def _write(path: Path, data: bytes) -> Path:
    """Write a file whole or not at all; a fault is one line naming it (InputError)."""
    with atomic_write(path, binary=True) as out:
        out.write(data)
    return path


def generate(model: CodeModel, out_dir: Path) -> list[Path]:
    """Write the saved CasADi functions of `model` with their manifest and README."""
    return write(model.flat, out_dir)


def casadi_c(model: CodeModel, out_dir: Path) -> list[Path]:
    """Run CasADi's own C code generator on every function: `<name>_casadi.c` and `.h`.

    The code is CasADi's (internal names prefixed `<name>_casadi_`); symid
    only puts its header on top. It is C99 but not warning-free under -Wall -Wextra.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    base = f"{model.name}_casadi"
    gen = ca.CodeGenerator(f"{base}.c", {"with_header": True})
    for f in functions(model.flat).values():
        gen.add(f)
    # CasADi writes its files without reporting a failed write (a full disk
    # leaves them short): it writes into a scratch folder beside the output,
    # the text is checked whole (the .c holds the code `dump` returns, the .h
    # ends with its closing) and each file is written whole or not at all
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=".casadi-") as scratch:
        gen.generate(scratch + "/")  # CasADi wants the folder with its trailing slash
        texts = {suffix: (Path(scratch) / f"{base}{suffix}").read_text() for suffix in (".c", ".h")}
    if gen.dump() not in texts[".c"] or not texts[".h"].rstrip().endswith("#endif"):
        raise InputError(f"{out_dir / base}.c: CasADi's code generation wrote an incomplete file "
                         "(is the disk full?); nothing written")
    written = []
    for suffix, body in texts.items():
        path = out_dir / f"{base}{suffix}"
        with atomic_write(path) as out:
            out.write(render("casadi/casadi_c.j2", name=model.name, body=body))
        written.append(path)
    return written
