"""The C target: a dependency-free C99 solver (`.h`, `.c`, Makefile) per mechanism."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import sympy as sp

from symid.codegen import friction
from symid.codegen.emit import CHUNK, Block, block, blocks, chunked, has_word
from symid.codegen.hoist import hoist
from symid.codegen.targets import c_fallback, c_loops, c_phase
from symid.codegen.targets.c_loops import Loops
from symid.codegen.targets.c_lu_tables import lu_tables
from symid.codegen.model import CodeModel
from symid.codegen.targets import c_sweep
from symid.codegen.render import render
from symid.codegen.targets.c_describe import describe
from symid.codegen.targets.c_printer import (DOUBLE, PRECISIONS, Printer, Scalar, c_double,  # noqa: F401
                                              printer as c_printer)
from symid.codegen.sparse import THRESHOLD, Coef, FoldedStep, Known, Plan, fold
from symid.model.motion import piece_tables, tables
from symid.numeric.newton import RULE
from symid.numeric.solve import JUMP_FLOOR, UNEXPLAINED

NAME = "c"


_PRINTER = Printer({"math_macros": {}})


def ccode(expr: sp.Expr) -> str:
    return _PRINTER.doprint(expr)


def _trig_map(ng: int) -> dict[sp.Expr, sp.Symbol]:
    """sin and cos of every body angle -> tr[2b], tr[2b + 1]: computed once per
    configuration and shared by Phi, Phi_q, gamma, Q^A and the reactions."""
    out: dict[sp.Expr, sp.Symbol] = {}
    for b in range(ng // 3):
        angle = sp.Symbol(f"q[{3 * b + 2}]", real=True)
        out[sp.sin(angle)] = sp.Symbol(f"tr[{2 * b}]", real=True)
        out[sp.cos(angle)] = sp.Symbol(f"tr[{2 * b + 1}]", real=True)
    return out


def _function(name: str, args: list[tuple[str, str]], exprs: list[sp.Expr],
              trig: dict[sp.Expr, sp.Symbol], printer: Callable[[sp.Expr], str] = ccode,
              real: str = "double", loops: Loops | None = None) -> dict[str, Any]:
    """One generated function: a kernel taking the angles' sines and cosines
    precomputed (`tr`), and the public signature without them; with `loops`,
    the outputs they cover are written by looped kernels (c_loops.j2)."""
    with_trig = any(a == "q" for _, a in args)
    kernel_args = args[:1] + [(f"const {real} *", "tr")] + args[1:] if with_trig else args
    mapped = [e.xreplace(trig) for e in exprs] if with_trig else list(exprs)
    looped = loops.kernels(name, [a for _, a in kernel_args], printer) if loops else []
    codes: list[Block] = (c_loops.remaining(mapped, loops.covered(name), printer) if loops and looped
                          else blocks(mapped, printer))

    def sig(items: list[tuple[str, str]]) -> str:
        return ", ".join([f"{ctype} {a}" for ctype, a in items] + [f"{real} *out"])

    chunks = [{"block": code, "unused": [a for _, a in kernel_args if not code.uses(a)]} for code in codes]
    return {"name": name, "signature": sig(kernel_args), "public_signature": sig(args), "chunks": chunks,
            "trig": with_trig, "call": ", ".join([a for _, a in kernel_args] + ["out"]), "loops": looped}


def _read(c: Coef) -> str:
    return f"lu[{c}]" if isinstance(c, int) else repr(c.value)


def _minus(c: Coef, var: str) -> str:
    """' - c * var', with a known 0 or +-1 left out (the same value exactly)."""
    if isinstance(c, Known) and c.value in (0.0, 1.0, -1.0):
        return "" if c.value == 0.0 else f" - {var}" if c.value == 1.0 else f" + {var}"
    return f" - {_read(c)} * {var}"


def _times(expr: str, c: Coef) -> str:
    """expr * c, with a known +-1 left out."""
    if isinstance(c, Known) and c.value in (1.0, -1.0):
        return expr if c.value == 1.0 else f"-({expr})"
    return f"({expr}) * {_read(c)}"


def _update(target: str, term: str) -> str:
    """target = target + term, term as _minus prints it."""
    return f"{target} {term[1]}= {term[3:]};" if term else ""


def _factor_lines(st: FoldedStep, P: str) -> list[str]:
    """The statements of one elimination step; known values are numbers."""
    if st.test == "fail":
        return ["return 1;  /* the known values fail the threshold test */"]
    variable = st.pivot is None
    lines = []
    if isinstance(st.test, tuple):  # decided at run time
        known_max, unknown = st.test
        if st.pivot is None:
            lines += [f"piv = lu[{st.pivot_slot}];", "cm = fabs(piv);"]
            lines += [f"cm = {P}_MAX(cm, {known_max!r});"] if known_max > 0 else []
        else:
            lines.append(f"cm = {known_max!r};")
        lines += [f"cm = {P}_MAX(cm, fabs(lu[{k}]));" for k in unknown]
        size = "fabs(piv)" if st.pivot is None else repr(abs(st.pivot))
        lines.append(f"if (!({size} >= {P}_THRESHOLD * cm){' || piv == 0.0' if variable else ''}) return 1;")
    if variable:
        lines.append(f"piv = lu[{st.pivot_slot}] = 1.0 / piv;")
    for m, source in st.scale:
        if variable:
            lines.append(f"lu[{m}] *= piv;" if isinstance(source, int) else f"lu[{m}] = {source.value!r} * piv;")
        elif isinstance(st.reciprocal, Known) and st.reciprocal.value != 1.0:
            lines.append(f"lu[{m}] = -lu[{m}];" if st.reciprocal.value == -1.0 else f"lu[{m}] *= {_read(st.reciprocal)};")
    for t, tc, mc, uc in st.updates:
        if isinstance(mc, Known) and isinstance(uc, Known):  # the product is known, the target is not
            term = f" - {mc.value * uc.value!r}"
        else:
            term = _minus(mc, _read(uc)) if isinstance(uc, int) else _minus(uc, _read(mc))
        lines.append(_update(f"lu[{t}]", term) if tc == t else f"lu[{t}] = {_read(tc)}{term};")
    return lines


def lu_chunks(plan: Plan, values: list[float | None], P: str, scalar: Scalar = DOUBLE) -> dict[str, Any]:
    """What templates/c/sparse_lu.j2 prints: the plan folded on the known
    values (per pattern slot, None where computed), printed as statements and
    grouped into functions of bounded size for each of the five straight-line
    passes (factor; solve forward and back; transposed solve forward and
    back). P: the upper-case prefix of the macros; scalar: the C type whose
    literals and fabs are printed."""
    steps = fold(plan, values)
    above: dict[int, list[tuple[int, Coef]]] = {}
    for f in steps:
        for c, coef in f.right:
            above.setdefault(c, []).append((f.step.row, coef))

    def forward(f: FoldedStep) -> list[str]:
        return [line for r, c in f.below if (line := _update(f"y[{r}]", _minus(c, f"y[{f.step.row}]")))]

    def back(f: FoldedStep) -> list[str]:
        terms = "".join(_minus(c, f"x[{col}]") for col, c in f.right)
        return [f"x[{f.step.col}] = {_times(f'y[{f.step.row}]{terms}', f.reciprocal)};"]

    def t_forward(f: FoldedStep) -> list[str]:
        terms = "".join(_minus(c, f"x[{r}]") for r, c in above.get(f.step.col, []))
        return [f"x[{f.step.row}] = {_times(f'b[{f.step.col}]{terms}', f.reciprocal)};"]

    def t_back(f: FoldedStep) -> list[str]:
        return [line for r, c in f.below if (line := _update(f"x[{f.step.row}]", _minus(c, f"x[{r}]")))]

    back_order = list(reversed(steps))

    def chunks(order: list[FoldedStep], lines: Callable[[FoldedStep], list[str]]) -> list[dict[str, Any]]:
        """Functions of bounded size; steps that print nothing (every value
        known) are left out, and a function with nothing to do is not
        emitted. `lu`, `piv`, `cm`: whether its code reads them, so that a
        function takes and declares only what it uses."""
        printed = [[scalar.relit(line) for line in ls] for f in order if (ls := lines(f))]
        weights = [1 + sum(1 + line.count(" * ") for line in ls) for ls in printed]
        out: list[dict[str, Any]] = []
        for group in chunked(printed, weights):
            body = [line for ls in group for line in ls]
            code = "\n".join(body)
            out.append({"lines": body, "lu": "lu[" in code, "piv": has_word(code, "piv"),
                        "cm": has_word(code, "cm")})
        return out

    passes: dict[str, Any] = {
        "factor_chunks": chunks(steps, lambda f: _factor_lines(f, P)),
        "forward_chunks": chunks(steps, forward),
        "back_chunks": chunks(back_order, back),
        "t_forward_chunks": chunks(steps, t_forward),
        "t_back_chunks": chunks(back_order, t_back),
    }
    # The pivots' spread, tested as the dense fallback tests it: the threshold
    # test compares a pivot with its own column only, so a pivot that cancels
    # to rounding (an exactly singular configuration) would pass it. The slots
    # keep reciprocals, whose spread is the pivots'.
    known = [abs(1.0 / f.pivot) for f in steps if f.pivot is not None and f.pivot != 0.0]
    passes["pivot_slots"] = [f.pivot_slot for f in steps if f.pivot is None]
    passes["known_reciprocals"] = (scalar.lit(min(known)), scalar.lit(max(known))) if known else None
    # the solves' fixed entry points take lu even where every value is a number
    passes["solve_reads_lu"] = any(ch["lu"] for k in ("forward_chunks", "back_chunks") for ch in passes[k])
    passes["f"] = scalar.suffix  # the suffix of the template's own literals
    passes["solve_t_reads_lu"] = any(ch["lu"] for k in ("t_forward_chunks", "t_back_chunks") for ch in passes[k])
    return passes


# Coordinates from which the sparse LU loops over index tables. Measured on
# a loaded machine (benchmarks/scale.py): at the ladder of 64 (ng 387) the
# straight-line code, with the known values folded, is 1.6 x faster; at the
# ladder of 256 (ng 1539) the tables are as fast or faster (the straight-line
# code outgrows the cache) and compile 4 x faster.
LU_TABLES_MIN = 1000


def _lu(model: CodeModel, fold_constants: bool, scalar: Scalar) -> dict[str, Any]:
    """The sparse LU's context: straight-line code (sparse_lu.j2), or index
    tables (sparse_lu_tables.j2) from LU_TABLES_MIN coordinates."""
    if model.flat.ng < LU_TABLES_MIN:
        return {"lu_tables": None, **lu_chunks(model.plan, _known(model, fold_constants), model.flat.name.upper(), scalar)}
    return {"lu_tables": lu_tables(model.plan), "known_reciprocals": None,
            "pivot_slots": [model.plan.slots[(st.row, st.col)] for st in model.plan.steps]}


def _all_blocks(functions: list[dict[str, Any]], prepare: list[Block]) -> list[Block]:
    return [ch["block"] for fn in functions for ch in fn["chunks"]] + prepare


def _known(model: CodeModel, fold_constants: bool) -> list[float | None]:
    """The entries of Phi_q that are numbers, per pattern slot (None: computed)."""
    return [float(e) if fold_constants and e.is_Number else None for _, _, e in model.flat.jac]


def _stride(model: CodeModel) -> int:
    """Doubles per work vector: the longest of q, the rows and the reactions."""
    f = model.flat
    return max(f.ng, f.nc, len(f.reactions), 1)


# Past this many coordinates the solver has no dense fallback: its NG^2
# reals (76 MB at the ladder of 512) would dwarf the sparse factors; a
# configuration the fixed pivots do not serve is factored again by a sparse
# LU with pivoting in a workspace of bounded size (c_fallback.py,
# templates/c/sparse_fallback.j2).
DENSE_LIMIT = 400


def dense_fallback(model: CodeModel) -> bool:
    return model.flat.ng <= DENSE_LIMIT


def work_size(model: CodeModel) -> int:
    """Reals of workspace a solver call needs before the prepared parameters
    (context()["work"] adds them): Phi_q's values, the sparse factors, the
    pivoting fallback (dense up to DENSE_LIMIT coordinates, sparse past
    it), eleven work vectors and the friction solve's."""
    f = model.flat
    fallback = f.ng * f.ng if dense_fallback(model) else c_fallback.work(model.plan, f.ng)
    return (len(f.jac) + model.plan.size + fallback + 11 * _stride(model)
            + friction.work(model.layout, f.options))


def state_size(model: CodeModel) -> int:
    """Doubles of trajectory state: q, qd, qdd, three earlier accelerations
    (statics: two earlier positions), the column scales of the jump check
    and the count of instants solved."""
    return 7 * model.flat.ng + 1


OUTPUTS_ARGS = ("t", "p", "q", "tr", "qd", "qdd", "lam", "reactions", "work", "iwork", "dense")


def _outputs_unused(velocity: bool, multipliers: bool, nr: int) -> list[str]:
    """The arguments of the template's `outputs` that the compiled groups
    leave unread (its one signature serves every output set)."""
    used: set[str] = set()
    if velocity:
        used |= {"t", "p", "q", "tr", "qd", "qdd", "work", "iwork", "dense"}
    if multipliers:
        used |= {"t", "p", "q", "tr", "lam", "work", "iwork", "dense"}
    if nr:
        used |= {"t", "p", "q", "tr", "lam", "reactions"}
    return [a for a in OUTPUTS_ARGS if a not in used]


def context(model: CodeModel, fold_constants: bool = True, precision: str = "double") -> dict[str, Any]:
    """Everything the C templates need, expressions already printed;
    fold_constants=False prints the factorization with every value read at
    run time (the same factors bitwise: for the tests); precision: "double"
    or "single" (float: literals, libm functions and epsilon of float)."""
    scalar = PRECISIONS[precision]
    f = model.flat
    o = f.options
    real = f"{f.name}_real"
    cq, cqd, ct, cp, clam = (f"const {real} *", "q"), (f"const {real} *", "qd"), (real, "t"), \
        (f"const {real} *", "p"), (f"const {real} *", "lam")
    trig = _trig_map(f.ng)
    printer = c_printer(f.name, scalar).doprint
    loops = c_loops.Loops.of(f, model.layout, model.loop_parts)
    used = f.phi + [e for _, _, e in f.jac]  # what is printed: a static function never called is an error
    dynamics = o.kind != "kinematics" and o.multipliers
    # parameter-only pieces read from p[NP + j], computed once per call by prepare
    lists = [f.phi, [e for _, _, e in f.jac], f.nu if o.velocity else [], f.gamma if o.velocity else [],
             f.applied if dynamics else [], f.mass if dynamics else [], f.reactions]
    # single precision: time as small phases, angles and angle rows by whole turns (c_phase)
    red = (c_phase.reduce(f.ng, lists[0], lists[1:], f.params, loops.covered("phi") if loops else ())
           if scalar.suffix else None)
    (phi, jac, nu, gamma, applied, mass, reactions), pieces = hoist(red.groups if red else lists, len(f.params))
    nph = len(red.nu) if red else 0
    off_nu = len(f.params) + len(pieces)  # prepared parameters: p | pieces | nu (hi, lo) pairs | phases
    if nph:
        phi, jac, nu, gamma, applied, mass, reactions = c_phase.place(
            [phi, jac, nu, gamma, applied, mass, reactions], off_nu + 2 * nph, nph)
    functions = [
        _function("phi", [cq, ct, cp], phi, trig, printer, real, loops),
        _function("phi_q", [cq, ct, cp], jac, trig, printer, real, loops),
    ]
    if o.velocity:
        functions += [_function("nu", [cq, ct, cp], nu, trig, printer, real, loops),
                      _function("gamma", [cq, cqd, ct, cp], gamma, trig, printer, real, loops)]
        used += f.nu + f.gamma
    if dynamics:
        functions += [_function("applied", [cq, cqd, ct, cp], applied, trig, printer, real, loops),
                      _function("mass", [cp], mass, trig, printer, real, loops)]
        used += f.applied
    if f.reactions:
        functions.append(_function("reactions", [cq, clam, ct, cp], reactions, trig, printer, real, loops))
        used += f.reactions
    prepare = [block(pieces[k:k + CHUNK], printer, offset=len(f.params) + k) for k in range(0, len(pieces), CHUNK)]
    ng, nc, nr = f.ng, f.nc, len(f.reactions)
    has = {g: int(g in o.outputs) for g in ("qdot", "qddot", "lambda", "reactions")}
    # a trajectory row: t, then each group in contract order
    row_parts, offset = [], 1
    sources = {"q": ("q", ng), "qdot": ("qd" if o.velocity else None, ng),
               "qddot": ("qdd" if o.velocity else None, ng), "lambda": ("lam", nc), "reactions": ("reac", nr)}
    for group in o.outputs:
        source, size = sources[group]
        row_parts.append((group, source, size, offset))
        offset += size
    stride = _stride(model)
    fr = friction.context(model.layout, o, offset, scalar.lit)  # joint friction (None: none, and no code for it)
    if fr is not None:
        functions += [_function("friction", [cq, cqd, ct, cp], fr["fixed"], trig, printer, real),
                      _function("friction_normal", [cq, clam, ct, cp], fr["normal"], trig, printer, real)]
        used += fr["fixed"] + fr["normal"]
    lu = _lu(model, fold_constants, scalar)
    d = describe(model, fr["row_width"] if fr else offset, functions, lu)
    # the trajectory's output vectors (variable, source, work vector): solved
    # straight into the row where it holds the source, else into the work vector
    placed = {source: offset for _, source, _, offset in row_parts if source}
    outputs = [(var, placed.get(source), slot)
               for var, source, slot in (("qn", "q", 4), ("qdn", "qd", 5), ("qddn", "qdd", 6), ("lam", "lam", 7),
                                         ("reac", "reac", 8))]
    npp = len(f.params) + len(pieces) + 3 * nph
    return {
        **c_phase.context(red, off_nu, len(f.params)),
        "name": f.name, "p": f.name, "P": f.name.upper(), "ng": ng, "nc": nc, "np_": len(f.params),
        "nnz": len(f.jac), "nr": nr, "row_width": fr["row_width"] if fr else offset, "friction": fr,
        "lu_size": model.plan.size,
        "work": work_size(model) + npp, "npp": npp,
        "prepare": prepare, "off_prep": work_size(model),
        "uses_powi": any(f"{f.name}_powi(" in e for b in _all_blocks(functions, prepare) for _, e in b.temps + b.outputs),
        "state": state_size(model), "stride": stride,
        "params": f.params, "derived": f.derived, "defaults": [scalar.lit(float(v)) for v in f.defaults],
        "jac_rows": [r for r, _, _ in f.jac], "jac_cols": [c for _, c, _ in f.jac],
        "functions": functions, "threshold": scalar.lit(THRESHOLD),
        **lu, "d": d, "d_lit": {"q0": [scalar.lit(v) for v in d["q0"]],
                                **{k: scalar.lit(float(d[k])) for k in ("t0", "t1", "tol")}},
        "max_newton": RULE.max_iterations, "floor_ulps": scalar.lit(RULE.floor_ulps),
        "jump_floor": scalar.lit(JUMP_FLOOR), "unexplained": scalar.lit(UNEXPLAINED),
        "velocity": o.velocity, "dynamics": dynamics,
        "multipliers": o.multipliers, "has": has, "row_parts": row_parts,
        "outputs_unused": _outputs_unused(o.velocity, o.multipliers, nr),
        "outputs": outputs,
        "loop_tables": loops.tables if loops else [],
        "dense_fallback": dense_fallback(model), "dense_limit": DENSE_LIMIT,
        "fb": None if dense_fallback(model) else c_fallback.context(model.plan, f.jac, ng),
        **c_sweep.context(model, printer, work_size(model) + npp,
                          fr["row_width"] if fr else offset),
        "nb": ng // 3, "singular": model.plan.singular,
        "splines": [_relit_tables(piece_tables(s), scalar) for s in tables(used)],
        "inf": scalar.lit(float("inf")), "nan": scalar.lit(float("nan")), "real": scalar.ctype, "f": scalar.suffix,
        "eps": scalar.eps, "precision": precision,
        "lm": {k: scalar.fn(k) for k in ("sin", "cos", "sqrt", "fabs", "fmax", "fmin", "tanh")},
        "comment_open": "/*", "comment_line": " *", "comment_close": "*/",
    }


def _relit_tables(table: dict[str, Any], scalar: Scalar) -> dict[str, Any]:
    """A spline's printed numbers as literals of the scalar type."""
    return {**table, **{k: [scalar.relit(v) for v in table[k]] for k in ("knots", "coef")},
            **{k: scalar.relit(table[k]) for k in ("lo", "hi")}}


def generate(model: CodeModel, out_dir: Path, fold_constants: bool = True, precision: str = "double") -> list[Path]:
    """Write `<name>_solver.h`, `<name>_solver.c` and a Makefile into out_dir
    (precision: "double" or "single", the type of `<name>_real`)."""
    return write(context(model, fold_constants, precision), out_dir)


def write(ctx: dict[str, Any], out_dir: Path) -> list[Path]:
    """Render a context into out_dir (its sizes, e.g. ctx["work"], are the code's)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    name = ctx["name"]
    files = {
        f"{name}_solver.h": render("c/solver.h.j2", **ctx),
        f"{name}_solver.c": render("c/solver.c.j2", **ctx),
        "Makefile": render("c/Makefile.j2", **ctx),
    }
    written = []
    for fname, text in files.items():
        path = out_dir / fname
        path.write_text(text)
        written.append(path)
    return written
