"""The C templates' context: the sections (lu, phase, checks, sweep, fb, d,
sens, lanes, the memory layout) composed with the solver's sizes, kernels and
printed settings into one typed record, rendered by `write`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from symid.codegen import friction
from symid.codegen.c import checks as c_checks
from symid.codegen.c import fallback as c_fallback
from symid.codegen.c import lanes as c_lanes
from symid.codegen.c import layout as c_layout
from symid.codegen.c import loops as c_loops
from symid.codegen.c import lu as c_lu
from symid.codegen.c import phase as c_phase
from symid.codegen.c import sensitivity as c_sens
from symid.codegen.c import setpoint as c_setpoint
from symid.codegen.c import sweep as c_sweep
from symid.codegen.c.checks import Checks
from symid.codegen.c.describe import Description, describe
from symid.codegen.c.fallback import Fallback
from symid.codegen.c.kernels import Kernel, function, trig_map
from symid.codegen.c.lanes import Lanes
from symid.codegen.c.layout import Vector, dense_fallback, state_layout, vectors, work_size
from symid.codegen.c.layout import stride as vector_stride
from symid.codegen.c.lu import LU
from symid.codegen.c.phase import Phase
from symid.codegen.c.printer import PRECISIONS, Scalar, printer as c_printer
from symid.codegen.c.sensitivity import Sensitivity
from symid.codegen.c.setpoint import Setpoint
from symid.codegen.c.sweep import Sweep
from symid.codegen.emit import CHUNK, Block, block
from symid.codegen.friction import Friction
from symid.codegen.hoist import hoist
from symid.codegen.model import CodeModel
from symid.codegen.render import render
from symid.codegen.sparse import REFINE_SPREAD, THRESHOLD
from symid.io.files import atomic_write
from symid.model.analysis import DEFAULT_COND_WARN
from symid.model.motion import piece_tables, tables
from symid.numeric.newton import RULE
from symid.numeric.solve import JUMP_FLOOR, UNEXPLAINED
from symid.numeric.stability import ESTIMATE_MARGIN, SCREEN


@dataclass(frozen=True)
class CContext:
    """Everything the C templates read, expressions already printed; the
    templates see each field as a name (`namespace`).

    Sizes: ng, nc, np_ (base parameters), nnz (Phi_q's pattern), nr
    (reactions), nb (bodies), row_width (ROW), work (WORK, reals), npp
    (prepared parameters), off_prep (where they start in work), stride
    (reals per work vector), state (STATE, reals).
    Literals (of the real type, printed): defaults, threshold, refine_spread,
    floor_ulps, jump_floor, unexplained, screen_ratio, cond_screen, inf, nan;
    real: the C type, f: its literals' suffix, eps: its epsilon, lm: libm's
    names for it; single_bound: single precision's bound against double
    (c.phase.single_bound), printed.
    row_parts: (group, source, size, offset) of the row; outputs: (variable,
    row offset or None, work vector) of the trajectory's outputs.
    """

    name: str
    p: str
    P: str
    ng: int
    nc: int
    np_: int
    nnz: int
    nr: int
    nb: int
    row_width: int
    work: int
    npp: int
    off_prep: int
    stride: int
    state: int
    state_layout: Vector
    vectors: Vector
    lu: LU
    phase: Phase
    checks: Checks
    sweep: Sweep
    fb: Fallback | None
    d: Description
    sens: Sensitivity | None
    friction: Friction | None
    lanes: Lanes | None
    setpoint: Setpoint | None
    functions: list[Kernel]
    prepare: list[Block]
    uses_powi: bool
    params: tuple[str, ...]
    derived: tuple[tuple[str, str], ...]
    defaults: list[str]
    jac_rows: list[int]
    jac_cols: list[int]
    threshold: str
    refine_spread: str
    max_newton: int
    floor_ulps: str
    jump_floor: str
    unexplained: str
    screen_ratio: str
    cond_screen: str
    velocity: bool
    dynamics: bool
    multipliers: bool
    has: dict[str, int]
    row_parts: list[tuple[str, str | None, int, int]]
    outputs_unused: list[str]
    outputs: list[tuple[str, int | None, int]]
    loop_tables: list[dict[str, Any]]
    dense_fallback: bool
    dense_limit: int
    singular: bool
    trig_loop: bool
    splines: list[dict[str, Any]]
    inf: str
    nan: str
    real: str
    f: str
    eps: str
    precision: str
    single_bound: str
    lm: dict[str, str]
    comment_open: str = "/*"
    comment_line: str = " *"
    comment_close: str = "*/"

    def namespace(self) -> dict[str, Any]:
        """The templates' names: each field, as it is (sections stay records)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


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


def _all_blocks(functions: list[Kernel], prepare: list[Block]) -> list[Block]:
    return [ch.block for fn in functions for ch in fn.chunks] + prepare


def context(model: CodeModel, fold_constants: bool = True, precision: str = "double",
            lanes: bool = False, setpoints: bool = True) -> CContext:
    """Everything the C templates need, expressions already printed;
    fold_constants=False prints the factorization with every value read at
    run time (the same factors bitwise: for the tests); precision: "double"
    or "single" (float: literals, libm functions and epsilon of float);
    lanes: the sweep's variants side by side (c.lanes), for the cache's
    build, which studies run; an exported solver (`symid generate`, for a
    controller or a board) has the one-by-one sweep, twice less code;
    setpoints=False leaves the set-point entries out (the c backend's
    build, which never calls them; an export has them)."""
    scalar = PRECISIONS[precision]
    f = model.flat
    o = f.options
    real = f"{f.name}_real"
    cq, cqd, ct, cp, clam = (f"const {real} *", "q"), (f"const {real} *", "qd"), (real, "t"), \
        (f"const {real} *", "p"), (f"const {real} *", "lam")
    trig = trig_map(f.ng)
    printer = c_printer(f.name, scalar).doprint
    loops = c_loops.Loops.of(f, model.layout, model.loop_parts)
    used = f.phi + [e for _, _, e in f.jac]  # what is printed: a static function never called is an error
    dynamics = o.kind != "kinematics" and o.multipliers
    # parameter-only pieces read from p[NP + j], computed once per call by prepare
    lists = [f.phi, [e for _, _, e in f.jac], f.nu if o.velocity else [], f.gamma if o.velocity else [],
             f.applied if dynamics else [], f.mass if dynamics else [], f.reactions]
    # single precision: time as small phases, angles and angle rows by whole turns (c.phase)
    red = (c_phase.reduce(f.ng, lists[0], lists[1:], f.params, loops.covered("phi") if loops else ())
           if scalar.suffix else None)
    (phi, jac, nu, gamma, applied, mass, reactions), pieces = hoist(red.groups if red else lists, len(f.params))
    nph = len(red.nu) if red else 0
    off_nu = len(f.params) + len(pieces)  # prepared parameters: p | pieces | nu (hi, lo) pairs | phases
    if nph:
        phi, jac, nu, gamma, applied, mass, reactions = c_phase.place(
            [phi, jac, nu, gamma, applied, mass, reactions], off_nu + 2 * nph, nph)
    functions = [
        function("phi", [cq, ct, cp], phi, trig, printer, real, loops),
        function("phi_q", [cq, ct, cp], jac, trig, printer, real, loops),
    ]
    if o.velocity:
        functions += [function("nu", [cq, ct, cp], nu, trig, printer, real, loops),
                      function("gamma", [cq, cqd, ct, cp], gamma, trig, printer, real, loops)]
        used += f.nu + f.gamma
    if dynamics:
        functions += [function("applied", [cq, cqd, ct, cp], applied, trig, printer, real, loops),
                      function("mass", [cp], mass, trig, printer, real, loops)]
        used += f.applied
    if f.reactions:
        functions.append(function("reactions", [cq, clam, ct, cp], reactions, trig, printer, real, loops))
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
    fr = friction.context(model.layout, o, offset, scalar.lit)  # joint friction (None: none, and no code for it)
    offset = fr.row_width if fr else offset  # the friction columns come before the sensitivities
    # parameter sensitivities after the row's other columns (None: not asked for, and no code for them)
    # its parameter-only pieces go after the phases in the prepared vector (p | pieces | phases | these)
    sens = c_sens.context(model, row_parts, offset, off_nu + 3 * nph, function, trig, printer, real, fr)
    if sens is not None:
        prepare += sens.prepare
        used += sens.exprs
        offset += sens.width
    if fr is not None:
        functions += [function("friction", [cq, cqd, ct, cp], fr.fixed, trig, printer, real),
                      function("friction_normal", [cq, clam, ct, cp], fr.normal, trig, printer, real)]
        used += fr.fixed + fr.normal
    lu = c_lu.context(model, fold_constants, scalar)
    d = describe(model, offset, functions, lu, scalar.lit, fr.fixed + fr.normal if fr else [])
    # every prepared value: NPP (with multipliers, the last one the refinement's gate of the call: PP_MIXED)
    npp = off_nu + 3 * nph + (sens.npieces if sens else 0) + (1 if o.multipliers else 0)
    work = work_size(model) + npp + (sens.work if sens else 0)
    # the trajectory's output vectors (variable, source, work vector): solved
    # straight into the row where it holds the source, else into the work vector
    placed = {source: offset for _, source, _, offset in row_parts if source}
    vec = vectors()
    outputs = [(var, placed.get(source), vec.at(var))
               for var, source in (("qn", "q"), ("qdn", "qd"), ("qddn", "qdd"), ("lam", "lam"), ("reac", "reac"))]
    # the drivers' values from the caller (c/setpoint.py; None: no driver)
    setpoint = (c_setpoint.context(model, red, function, trig, printer, real, sens.stages if sens else ())
                if setpoints else None)
    ctx = CContext(
        name=f.name, p=f.name, P=f.name.upper(), ng=ng, nc=nc, np_=len(f.params), nnz=len(f.jac), nr=nr,
        nb=ng // 3, row_width=offset, work=work, npp=npp, off_prep=work_size(model), stride=vector_stride(model),
        state=state_layout(ng).size, state_layout=state_layout(ng), vectors=vec,
        lu=lu, phase=c_phase.context(red, off_nu, len(f.params)),
        checks=c_checks.context(outputs, ng, nc, o.velocity, o.multipliers, nr),
        sweep=c_sweep.context(model, printer, work, offset, scalar.lit, precision),
        fb=None if dense_fallback(model) else c_fallback.context(model.plan, f.jac, ng),
        d=d, sens=sens, friction=fr, lanes=None, setpoint=setpoint, functions=functions, prepare=prepare,
        uses_powi=any(f"{f.name}_powi(" in e for b in _all_blocks(functions + (sens.functions if sens else []),
                                                                  prepare) for _, e in b.temps + b.outputs)
        or bool(setpoint and setpoint.uses_powi),
        params=f.params, derived=f.derived, defaults=[scalar.lit(float(v)) for v in f.defaults],
        jac_rows=[r for r, _, _ in f.jac], jac_cols=[c for _, c, _ in f.jac],
        threshold=scalar.lit(THRESHOLD), refine_spread=scalar.lit(REFINE_SPREAD),
        max_newton=RULE.max_iterations, floor_ulps=scalar.lit(RULE.floor_ulps),
        jump_floor=scalar.lit(JUMP_FLOOR), unexplained=scalar.lit(UNEXPLAINED),
        screen_ratio=scalar.lit(DEFAULT_COND_WARN / SCREEN),
        cond_screen=scalar.lit(DEFAULT_COND_WARN / ESTIMATE_MARGIN),
        velocity=o.velocity, dynamics=dynamics, multipliers=o.multipliers, has=has, row_parts=row_parts,
        outputs_unused=_outputs_unused(o.velocity, o.multipliers, nr), outputs=outputs,
        loop_tables=loops.tables if loops else [],
        dense_fallback=dense_fallback(model), dense_limit=c_layout.DENSE_LIMIT,
        singular=model.plan.singular, trig_loop=ng >= c_lu.LU_TABLES_MIN,
        splines=[_relit_tables(piece_tables(s), scalar) for s in tables(used)],
        inf=scalar.lit(float("inf")), nan=scalar.lit(float("nan")), real=scalar.ctype, f=scalar.suffix,
        eps=scalar.eps, precision=precision, single_bound=scalar.lit(c_phase.single_bound(fr is not None)),
        lm={k: scalar.fn(k) for k in ("sin", "cos", "sqrt", "fabs", "fmax", "fmin", "tanh")},
    )
    # the sweep's variants side by side (None: one by one)
    return dataclasses.replace(ctx, lanes=c_lanes.context(ctx)) if lanes else ctx


def _relit_tables(table: dict[str, Any], scalar: Scalar) -> dict[str, Any]:
    """A spline's printed numbers as literals of the scalar type."""
    return {**table, **{k: [scalar.relit(v) for v in table[k]] for k in ("knots", "coef")},
            **{k: scalar.relit(table[k]) for k in ("lo", "hi")}}


TEMPLATES = ("c/solver.c.j2", "c/solver.h.j2", "c/Makefile.j2")  # what `write` renders


def generate(model: CodeModel, out_dir: Path, fold_constants: bool = True, precision: str = "double") -> list[Path]:
    """Write `<name>_solver.h`, `<name>_solver.c` and a Makefile into out_dir
    (precision: "double" or "single", the type of `<name>_real`)."""
    return write(context(model, fold_constants, precision), out_dir)


def write(ctx: CContext, out_dir: Path) -> list[Path]:
    """Render a context into out_dir (its sizes, e.g. ctx.work, are the code's)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names = ctx.namespace()
    files = {
        f"{ctx.name}_solver.h": render("c/solver.h.j2", **names),
        f"{ctx.name}_solver.c": render("c/solver.c.j2", **names),
        "Makefile": render("c/Makefile.j2", **names),
    }
    written = []
    for fname, text in files.items():
        path = out_dir / fname
        with atomic_write(path) as out:  # whole or not at all, a fault named in one line (disk full)
            out.write(text)
        written.append(path)
    return written
