"""The straight-line sparse LU of the C target: the planned factorization's
steps as C statements, in chunks (sparse_lu.j2), with the values known at
generation folded in."""

from __future__ import annotations

from typing import Any, Callable

from symid.codegen.emit import chunked, has_word
from symid.codegen.sparse import Coef, FoldedStep, Known, Plan, fold
from symid.codegen.targets.c_printer import DOUBLE, Scalar


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
    passes["f"] = scalar.suffix  # the suffix of the template's own literals
    passes["solve_t_reads_lu"] = any(ch["lu"] for k in ("t_forward_chunks", "t_back_chunks") for ch in passes[k])
    return passes


# Coordinates from which the sparse LU loops over index tables. Measured on
