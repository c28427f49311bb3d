"""The straight-line sparse LU of the C target: the planned factorization's
steps as C statements, in chunks (sparse_lu.j2), with the values known at
generation folded in."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from symid.codegen.c import loops
from symid.codegen.c.lu_runs import lu_runs, rolled
from symid.codegen.c.lu_tables import lu_tables
from symid.codegen.c.printer import DOUBLE, Scalar
from symid.codegen.emit import chunked, has_word
from symid.codegen.model import CodeModel
from symid.codegen.sparse import Coef, FoldedStep, Known, Plan, fold


def _read(c: Coef) -> str:
    return f"lu[{c}]" if isinstance(c, int) else repr(c.value)


def _minus(c: Coef, var: str) -> str:
    """' - c * var', with a known 0 or +-1 left out (the same value exactly)."""
    if isinstance(c, Known) and c.value in (0.0, 1.0, -1.0):
        return "" if c.value == 0.0 else f" - {var}" if c.value == 1.0 else f" + {var}"
    return f" - ({_read(c)} * {var})"  # the product in parentheses: MISRA C:2012 12.1


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
        lines.append(f"if (!({size} >= ({P}_THRESHOLD * cm)){' || (piv == 0.0)' if variable else ''}) {{ return 1; }}")
    if variable:
        lines += [f"lu[{st.pivot_slot}] = 1.0 / piv;", f"piv = lu[{st.pivot_slot}];"]  # no assignment in an expression (13.4)
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
    per_step: list[list[list[str]]] = []  # per pass, per step that prints something, its statements

    def chunks(order: list[FoldedStep], lines: Callable[[FoldedStep], list[str]]) -> list[dict[str, Any]]:
        """Functions of bounded size; steps that print nothing (every value
        known) are left out, and a function with nothing to do is not
        emitted. `lu`, `piv`, `cm`: whether its code reads them, so that a
        function takes and declares only what it uses."""
        printed = [[scalar.relit(line) for line in ls] for f in order if (ls := lines(f))]
        per_step.append(printed)
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
    passes["rolled"] = False  # c_lu_runs.rolled: the passes as runs
    passes["step_lines"] = dict(zip(("factor_chunks", "forward_chunks", "back_chunks", "t_forward_chunks",
                                     "t_back_chunks"), per_step))
    # The pivots' spread, tested as the dense fallback tests it: the threshold
    # test compares a pivot with its own column only, so a pivot that cancels
    # to rounding (an exactly singular configuration) would pass it. The slots
    # keep reciprocals, whose spread is the pivots'.
    known = [abs(1.0 / f.pivot) for f in steps if f.pivot is not None and f.pivot != 0.0]
    passes["pivot_slots"] = [f.pivot_slot for f in steps if f.pivot is None]
    passes["known_reciprocals"] = (scalar.lit(min(known)), scalar.lit(max(known))) if known else None
    # the conditioning screen (solver.c.j2, screen): each pivot's reciprocal
    # with its row and column, a slot where computed, a number where known
    passes["screen"] = {"slots": [(f.pivot_slot, f.step.row, f.step.col) for f in steps if f.pivot is None],
                        "known": [(scalar.lit(abs(1.0 / f.pivot)), f.step.row, f.step.col) for f in steps
                                  if f.pivot is not None and f.pivot != 0.0]}
    # the solves' fixed entry points take lu even where every value is a number
    passes["solve_reads_lu"] = any(ch["lu"] for k in ("forward_chunks", "back_chunks") for ch in passes[k])
    passes["solve_t_reads_lu"] = any(ch["lu"] for k in ("t_forward_chunks", "t_back_chunks") for ch in passes[k])
    return passes



Chunks = list[dict[str, Any]]  # per function: "lines", and whether it reads "lu", "piv", "cm"


@dataclass(frozen=True)
class LU:
    """What the templates print for the fixed sparse LU (sparse_lu.j2,
    sparse_lu_tables.j2, sparse_lu_runs.j2, the screen in solver.c.j2).

    Attributes:
        size: reals of the sparse factors (LU_SIZE).
        tables: index tables (lu_tables), for a large mechanism; else None.
        runs: the tables' passes as runs (lu_runs), or None.
        pivot_slots: the factor slots of the pivots computed at run time.
        known_reciprocals: (min, max) of the known pivots' reciprocals, printed, or None.
        screen: the conditioning screen's pivots: "slots" (slot, row, col)
            and "known" (printed |1/pivot|, row, col).
        factor_chunks .. t_back_chunks: the straight-line passes (empty with tables).
        rolled: the passes rolled into runs (lu_runs.rolled).
        step_lines: per pass, per step, its statements (describe's count).
        solve_reads_lu, solve_t_reads_lu: whether the (transposed) solves read lu.
    """

    size: int
    tables: dict[str, Any] | None
    runs: dict[str, Any] | None
    pivot_slots: list[int]
    known_reciprocals: tuple[str, str] | None
    screen: dict[str, list[tuple[Any, int, int]]]
    factor_chunks: Chunks = field(default_factory=list)
    forward_chunks: Chunks = field(default_factory=list)
    back_chunks: Chunks = field(default_factory=list)
    t_forward_chunks: Chunks = field(default_factory=list)
    t_back_chunks: Chunks = field(default_factory=list)
    rolled: bool = False
    step_lines: dict[str, list[list[str]]] = field(default_factory=dict)
    solve_reads_lu: bool = False
    solve_t_reads_lu: bool = False


# a loaded machine (benchmarks/scale.py): at the ladder of 64 (ng 387) the
# straight-line code, with the known values folded, is 1.6 x faster; at the
# ladder of 256 (ng 1539) the tables are as fast or faster (the straight-line
# code outgrows the cache) and compile 4 x faster. The folded code rolled into
# runs (lu_runs.rolled) beats both where the steps repeat (ladder of 512:
# LU instructions per instant 781k on tables, 140k rolled), so the tables serve
# only a large mechanism whose steps do not repeat.
LU_TABLES_MIN = 1000


def known(model: CodeModel, fold_constants: bool) -> list[float | None]:
    """The entries of Phi_q that are numbers, per pattern slot (None: computed)."""
    return [float(e) if fold_constants and e.is_Number else None for _, _, e in model.flat.jac]


def context(model: CodeModel, fold_constants: bool, scalar: Scalar) -> LU:
    """The sparse LU's context: straight-line code with the known values
    folded (sparse_lu.j2), rolled into runs where its steps repeat
    (lu_runs.rolled: a chain's code does not grow with its length);
    past LU_TABLES_MIN coordinates where it does not roll, index tables
    (sparse_lu_tables.j2, as runs where those repeat)."""
    P = model.flat.name.upper()
    size = model.plan.size
    if model.flat.ng < LU_TABLES_MIN or not model.plan.singular:
        passes = lu_chunks(model.plan, known(model, fold_constants), P, scalar)
        # a mechanism as small as the bundled examples keeps its code as it was
        roll = None if model.plan.singular or model.flat.ng < loops.LOOP_MIN else rolled(passes)
        if roll is not None or model.flat.ng < LU_TABLES_MIN:
            return LU(size=size, tables=None, runs=None, **(roll or passes))
    tables = lu_tables(model.plan)
    runs = None if model.plan.singular else lu_runs(tables, model.flat.options.multipliers, scalar.fn("fabs"), P,
                                                    scalar.suffix)
    slots = [model.plan.slots[(st.row, st.col)] for st in model.plan.steps]
    return LU(size=size, tables=tables, runs=runs, known_reciprocals=None, pivot_slots=slots,
              screen={"slots": [(s, st.row, st.col) for s, st in zip(slots, model.plan.steps)], "known": []})
