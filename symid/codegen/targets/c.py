"""The C target: a dependency-free C99 solver (`.h`, `.c`, Makefile) per mechanism."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import sympy as sp

from symid.codegen import friction
from symid.codegen.emit import CHUNK, Block, block, blocks
from symid.codegen.hoist import hoist
from symid.codegen.targets import c_fallback, c_loops, c_phase
from symid.codegen.targets.c_loops import Loops
from symid.codegen.targets.c_lu import lu_chunks  # noqa: F401 (tests build chunks through c)
from symid.codegen.targets.c_lu_runs import lu_runs, rolled
from symid.codegen.targets.c_lu_tables import lu_tables
from symid.codegen.model import CodeModel
from symid.codegen.targets import c_checks, c_describe, c_lanes, c_sens, c_setpoint, c_sweep
from symid.codegen.render import render
from symid.codegen.targets.c_describe import describe
from symid.codegen.targets.c_printer import (DOUBLE, PRECISIONS, Printer, Scalar, c_double,  # noqa: F401
                                              printer as c_printer)
from symid.codegen.sparse import REFINE_SPREAD, THRESHOLD
from symid.io.files import atomic_write
from symid.model.motion import piece_tables, tables
from symid.numeric.newton import RULE
from symid.numeric.solve import JUMP_FLOOR, UNEXPLAINED
from symid.model.analysis import DEFAULT_COND_WARN
from symid.numeric.stability import ESTIMATE_MARGIN, SCREEN

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
    looped = loops.kernels(name, [a for _, a in kernel_args], printer, real) if loops else []
    codes: list[Block] = (c_loops.remaining(mapped, loops.covered(name), printer) if loops and looped
                          else blocks(mapped, printer))

    def sig(items: list[tuple[str, str]]) -> str:
        return ", ".join([f"{ctype} {a}" for ctype, a in items] + [f"{real} *out"])

    chunks = [{"block": code, "unused": [a for _, a in kernel_args if not code.uses(a)]} for code in codes]
    return {"name": name, "signature": sig(kernel_args), "public_signature": sig(args), "chunks": chunks,
            "trig": with_trig, "call": ", ".join([a for _, a in kernel_args] + ["out"]), "loops": looped}


# a loaded machine (benchmarks/scale.py): at the ladder of 64 (ng 387) the
# straight-line code, with the known values folded, is 1.6 x faster; at the
# ladder of 256 (ng 1539) the tables are as fast or faster (the straight-line
# code outgrows the cache) and compile 4 x faster. The folded code rolled into
# runs (c_lu_runs.rolled) beats both where the steps repeat (ladder of 512:
# LU instructions per instant 781k on tables, 140k rolled), so the tables serve
# only a large mechanism whose steps do not repeat.
LU_TABLES_MIN = 1000


def _lu(model: CodeModel, fold_constants: bool, scalar: Scalar) -> dict[str, Any]:
    """The sparse LU's context: straight-line code with the known values
    folded (sparse_lu.j2), rolled into runs where its steps repeat
    (c_lu_runs.rolled: a chain's code does not grow with its length);
    past LU_TABLES_MIN coordinates where it does not roll, index tables
    (sparse_lu_tables.j2, as runs where those repeat)."""
    P = model.flat.name.upper()
    if model.flat.ng < LU_TABLES_MIN or not model.plan.singular:
        passes = lu_chunks(model.plan, _known(model, fold_constants), P, scalar)
        # a mechanism as small as the bundled examples keeps its code as it was
        roll = None if model.plan.singular or model.flat.ng < c_loops.LOOP_MIN else rolled(passes)
        if roll is not None or model.flat.ng < LU_TABLES_MIN:
            return {"lu_tables": None, "lu_runs": None, **(roll or passes)}
    tables = lu_tables(model.plan)
    runs = None if model.plan.singular else lu_runs(tables, model.flat.options.multipliers, scalar.fn("fabs"), P,
                                                    scalar.suffix)
    slots = [model.plan.slots[(st.row, st.col)] for st in model.plan.steps]
    return {"lu_tables": tables, "lu_runs": runs, "known_reciprocals": None, "pivot_slots": slots,
            "screen": {"slots": [(s, st.row, st.col) for s, st in zip(slots, model.plan.steps)], "known": []}}


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
    it), twelve work vectors and the friction solve's."""
    f = model.flat
    fallback = f.ng * f.ng if dense_fallback(model) else c_fallback.work(model.plan, f.ng)
    return (len(f.jac) + model.plan.size + fallback + 12 * _stride(model)
            + friction.work(model.layout, f.options))


def state_size(model: CodeModel) -> int:
    """Doubles of trajectory state: q, qd, qdd, three earlier accelerations
    (statics: two earlier positions), the column scales of the jump check,
    the row scales of the conditioning screen and the count of instants
    solved (last)."""
    return 8 * model.flat.ng + 1


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


def context(model: CodeModel, fold_constants: bool = True, precision: str = "double",
            lanes: bool = False) -> dict[str, Any]:
    """Everything the C templates need, expressions already printed;
    fold_constants=False prints the factorization with every value read at
    run time (the same factors bitwise: for the tests); precision: "double"
    or "single" (float: literals, libm functions and epsilon of float);
    lanes: the sweep's variants side by side (c_lanes), for the cache's
    build, which studies run; an exported solver (`symid generate`, for a
    controller or a board) has the one-by-one sweep, twice less code."""
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
    offset = fr["row_width"] if fr else offset  # the friction columns come before the sensitivities
    # parameter sensitivities after the row's other columns (None: not asked for, and no code for them)
    # its parameter-only pieces go after the phases in the prepared vector (p | pieces | phases | these)
    sens = c_sens.context(model, row_parts, offset, off_nu + 3 * nph, _function, trig, printer, real, fr)
    if sens is not None:
        prepare += sens["prepare"]
        used += sens["exprs"]
        offset += sens["width"]
    if fr is not None:
        functions += [_function("friction", [cq, cqd, ct, cp], fr["fixed"], trig, printer, real),
                      _function("friction_normal", [cq, clam, ct, cp], fr["normal"], trig, printer, real)]
        used += fr["fixed"] + fr["normal"]
    lu = _lu(model, fold_constants, scalar)
    d = describe(model, offset, functions, lu, fr["fixed"] + fr["normal"] if fr else [])
    npp = off_nu + 3 * nph + (sens["npieces"] if sens else 0)  # every prepared value: NPP
    # the trajectory's output vectors (variable, source, work vector): solved
    # straight into the row where it holds the source, else into the work vector
    placed = {source: offset for _, source, _, offset in row_parts if source}
    outputs = [(var, placed.get(source), slot)
               for var, source, slot in (("qn", "q", 4), ("qdn", "qd", 5), ("qddn", "qdd", 6), ("lam", "lam", 7),
                                         ("reac", "reac", 8))]
    ctx = {
        **c_phase.context(red, off_nu, len(f.params)),
        "name": f.name, "p": f.name, "P": f.name.upper(), "ng": ng, "nc": nc, "np_": len(f.params),
        "nnz": len(f.jac), "nr": nr, "row_width": offset, "friction": fr,
        "lu_size": model.plan.size,
        "work": work_size(model) + npp + (sens["work"] if sens else 0), "npp": npp, "sens": sens,
        "prepare": prepare, "off_prep": work_size(model),
        "uses_powi": any(f"{f.name}_powi(" in e for b in _all_blocks(functions + (sens["functions"] if sens else []),
                                                                     prepare) for _, e in b.temps + b.outputs),
        "state": state_size(model), "stride": stride,
        "params": f.params, "derived": f.derived, "defaults": [scalar.lit(float(v)) for v in f.defaults],
        "jac_rows": [r for r, _, _ in f.jac], "jac_cols": [c for _, c, _ in f.jac],
        "functions": functions, "threshold": scalar.lit(THRESHOLD), "refine_spread": scalar.lit(REFINE_SPREAD),
        **lu, "d": d, "d_lit": {"q0": [scalar.lit(v) for v in d["q0"]],
                                **{k: scalar.lit(float(d[k])) for k in ("t0", "t1", "tol")}},
        "max_newton": RULE.max_iterations, "floor_ulps": scalar.lit(RULE.floor_ulps),
        "jump_floor": scalar.lit(JUMP_FLOOR), "unexplained": scalar.lit(UNEXPLAINED),
        "screen_ratio": scalar.lit(DEFAULT_COND_WARN / SCREEN),
        "cond_screen": scalar.lit(DEFAULT_COND_WARN / ESTIMATE_MARGIN),
        "velocity": o.velocity, "dynamics": dynamics,
        "multipliers": o.multipliers, "has": has, "row_parts": row_parts,
        "outputs_unused": _outputs_unused(o.velocity, o.multipliers, nr),
        "outputs": outputs, **c_checks.context(outputs, ng, nc, o.velocity, o.multipliers, nr),
        "loop_tables": loops.tables if loops else [],
        "dense_fallback": dense_fallback(model), "dense_limit": DENSE_LIMIT,
        "per_op": c_describe.PER_OP, "per_libm": c_describe.PER_LIBM, "per_iteration": c_describe.PER_ITERATION,
        "per_call": c_describe.PER_CALL,
        "fb": None if dense_fallback(model) else c_fallback.context(model.plan, f.jac, ng),
        **c_sweep.context(model, printer, work_size(model) + npp + (sens["work"] if sens else 0),
                          offset),
        "nb": ng // 3, "singular": model.plan.singular, "trig_loop": ng >= LU_TABLES_MIN,
        "splines": [_relit_tables(piece_tables(s), scalar) for s in tables(used)],
        "inf": scalar.lit(float("inf")), "nan": scalar.lit(float("nan")), "real": scalar.ctype, "f": scalar.suffix,
        "eps": scalar.eps, "precision": precision,
        "lm": {k: scalar.fn(k) for k in ("sin", "cos", "sqrt", "fabs", "fmax", "fmin", "tanh")},
        "comment_open": "/*", "comment_line": " *", "comment_close": "*/",
    }
    # the drivers' values from the caller (c_setpoint; None: no driver)
    ctx["setpoint"] = c_setpoint.context(model, red, _function, trig, printer, real, sens["stages"] if sens else ())
    ctx["uses_powi"] = ctx["uses_powi"] or bool(ctx["setpoint"] and ctx["setpoint"]["uses_powi"])
    ctx["lanes"] = c_lanes.context(ctx) if lanes else None  # the sweep's variants side by side (None: one by one)
    return ctx


def _relit_tables(table: dict[str, Any], scalar: Scalar) -> dict[str, Any]:
    """A spline's printed numbers as literals of the scalar type."""
    return {**table, **{k: [scalar.relit(v) for v in table[k]] for k in ("knots", "coef")},
            **{k: scalar.relit(table[k]) for k in ("lo", "hi")}}


def generate(model: CodeModel, out_dir: Path, fold_constants: bool = True, precision: str = "double") -> list[Path]:
    """Write `<name>_solver.h`, `<name>_solver.c` and a Makefile into out_dir
    (precision: "double" or "single", the type of `<name>_real`)."""
    return write(context(model, fold_constants, precision), out_dir)


TEMPLATES = ("c/solver.c.j2", "c/solver.h.j2", "c/Makefile.j2")  # what `write` renders


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
        with atomic_write(path) as out:  # whole or not at all, a fault named in one line (disk full)
            out.write(text)
        written.append(path)
    return written
