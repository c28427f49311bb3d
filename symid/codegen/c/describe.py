"""What the C header says about the mechanism besides the calls: the row's
column names and units, the parameters' names (with the file's own comment,
and whether anything reads them), the assembled q0, the file's time grid and
the operation count of one instant, counted on the emitted code."""

from __future__ import annotations

import re
from pathlib import Path
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import sympy as sp

from symid.codegen.c.kernels import Kernel
from symid.codegen.c.lu import LU
from symid.codegen.model import CodeModel

# the dimension of a row column, by its name's last part (angles in radians;
# lengths, forces and time in the file's consistent units)
_UNITS = {"t": "time", "x": "length", "y": "length", "phi": "rad", "vx": "length/time", "vy": "length/time",
          "omega": "rad/time", "ax": "length/time^2", "ay": "length/time^2", "alpha": "rad/time^2",
          "Fx": "force", "Fy": "force", "T": "force*length"}
_BINARY = re.compile(r"(?<=[\w)\]])\s*[-+*/]\s*(?=[\w(.])")
_CALL = re.compile(r"\b[a-z_]\w*\(")


def unit(column: str) -> str:
    """The dimension of a contract column ('crank.phi' -> rad); a multiplier's
    is its constraint row's reaction (force, or torque for an angle row)."""
    if column.startswith("d(") and ")/d(" in column:  # a sensitivity d(COLUMN)/d(NAME)
        of, by = column[2:-1].split(")/d(")
        return f"{unit(of)} per unit of {by}" if unit(of) else ""
    last = column.rsplit(".", 1)[-1].split("_")[0]
    if last.startswith("lambda"):
        return "force or torque, per its row"
    return _UNITS.get(last, "")


def ops(code: str) -> int:
    """Floating operations of printed C: binary + - * / and function calls
    (an index expression such as lu[3] counts nothing)."""
    code = re.sub(r"\[[^\]]*\]", "[]", code)
    return len(_BINARY.findall(code)) + len(_CALL.findall(code))


# The worst case's charge per counted operation (its loads, stores and index
# arithmetic included) and per libm call (sin, cos, exp, atan2 ... of the
# real type on its own FPU, in their usual range), and the calls' and loops'
# overhead: assumptions of the stated worst case, which test_c_edges checks
# under callgrind on the host for every bundled example.
PER_OP = 12
PER_LIBM = 300
PER_ITERATION = 400
PER_CALL = 3000
_LIBM = re.compile(r"\b(?:sin|cos|tan|exp|log|atan2|atan|asin|acos|sqrt|tanh|sinh|cosh|pow)f?\(")


def worst_case(counts: dict[str, int], calls: dict[str, int], lu_ops: dict[str, int], ng: int, nc: int,
               nb: int, nr: int) -> dict[str, int]:
    """A bound on one instant call's work, every Newton iteration taken (the
    cap reached) and every factorization going through the pivoting
    fallback (bounded by a dense LU's operations): operations and libm calls
    outside the iterations (fixed) and per iteration (iter), and the
    instructions they are charged (PER_OP, PER_LIBM, PER_ITERATION, PER_CALL)."""
    dense_factor = 2 * ng ** 3 // 3 + 3 * ng * ng  # eliminations, the pivot search and row swaps
    solve = lu_ops["forward"] + lu_ops["back"] + 2 * ng * ng  # sparse, then dense
    factor = counts.get("phi_q", 0) * 2 + lu_ops["factor"] + dense_factor + nb  # pivots' spread
    it = counts.get("phi", 0) + factor + solve + 12 * ng + 2 * nc  # correct, trig_step, maxabs
    libm_it = calls.get("phi", 0) + 2 * calls.get("phi_q", 0) + 2 * nb  # a rotation past its Taylor range
    fixed = (counts.get("phi", 0) + factor + sum(counts.get(k, 0) for k in ("nu", "gamma", "applied", "mass",
                                                                              "reactions", "friction",
                                                                              "friction_normal"))
             + 3 * solve + lu_ops["t_forward"] + lu_ops["t_back"] + 6 * ng + 2 * nc + nr)
    libm_fixed = (calls.get("phi", 0) + 2 * calls.get("phi_q", 0) + 2 * nb
                  + sum(calls.get(k, 0) for k in ("nu", "gamma", "applied", "reactions", "friction",
                                                  "friction_normal")))
    return {"ops_fixed": fixed, "ops_iter": it, "libm_fixed": libm_fixed, "libm_iter": libm_it,
            "fixed": PER_CALL + PER_OP * fixed + PER_LIBM * libm_fixed,
            "iter": PER_ITERATION + PER_OP * it + PER_LIBM * libm_it}


def file_comments(source: str, names: Sequence[str]) -> dict[str, str]:
    """The trailing comment of each parameter's line in the file's
    [parameters] table ('# crank radius, m'), where the file has one."""
    path = Path(source)
    if not path.is_file():
        return {}
    out: dict[str, str] = {}
    section = ""
    for line in path.read_text(errors="replace").splitlines():
        head = re.match(r"\s*\[+\s*([\w.]+)\s*\]+", line)
        if head:
            section = head.group(1)
            continue
        m = re.match(r"\s*([\w]+)\s*=[^#]*#\s*(.+?)\s*$", line)
        if section == "parameters" and m and m.group(1) in names:
            out[m.group(1)] = m.group(2).replace("*/", "* /")
    return out


def read_params(model: CodeModel, extra: Sequence[sp.Expr] = ()) -> set[int]:
    """Indices k of the parameters p[k] that some emitted expression reads;
    extra: the target's own kernels' (joint friction's coefficients)."""
    f = model.flat
    exprs = [*f.phi, *(e for _, _, e in f.jac), *f.reactions, *extra]
    if f.options.velocity:
        exprs += [*f.nu, *f.gamma]
    if f.options.kind != "kinematics" and f.options.multipliers:  # the template's `dynamics`
        exprs += [*f.applied, *f.mass]
    names = {str(s) for e in exprs for s in sp.sympify(e).free_symbols}
    return {k for k in range(len(f.params)) if f"p[{k}]" in names}


def c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


@dataclass(frozen=True)
class Description:
    """What the header says about the mechanism (describe.h.j2, describe.c.j2: `d`).

    Attributes:
        columns: per row column its name, C string and unit.
        param_info: per parameter its name, C string, file comment, whether
            anything reads it, and its definition where derived.
        unread: the parameters nothing reads.
        q0, t0, t1, steps, tol: the assembled q0 and the file's grid; lit:
            q0 (a list), t0, t1 and tol printed as literals of the real type.
        ops: operations per kernel and LU pass; ops_instant: of a usual instant.
        worst: the worst case's operations, libm calls and instructions (worst_case).
        per_op, per_libm, per_iteration, per_call: the worst case's charges.
    """

    columns: list[dict[str, str]]
    param_info: list[dict[str, Any]]
    unread: list[str]
    q0: list[float]
    t0: float
    t1: float
    steps: int
    tol: float
    lit: dict[str, Any]
    ops: dict[str, int]
    ops_instant: int
    worst: dict[str, int]
    body_names: list[str]
    per_op: int = PER_OP
    per_libm: int = PER_LIBM
    per_iteration: int = PER_ITERATION
    per_call: int = PER_CALL


def describe(model: CodeModel, row_width: int, functions: Sequence[Kernel], lu: LU, lit: Callable[[float], str],
             extra: Sequence[sp.Expr] = ()) -> Description:
    """The header's description (names, units, grid, q0, operation counts);
    lit: prints a literal of the real type; extra: expressions of kernels
    beyond the flat model's (read_params)."""
    f = model.flat
    mech = model.layout.mechanism
    a = mech.analysis
    columns = list(model.row_columns[:row_width])
    comments = file_comments(mech.source, f.params)
    read = read_params(model, extra)
    params = [{"name": n, "string": c_string(n), "comment": comments.get(n, ""), "read": k in read,
               "derived": str(mech.parameters[n]) if not sp.sympify(mech.parameters[n]).is_Number else ""}
              for k, n in enumerate(f.params)]

    def printed(fn: Kernel) -> list[str]:
        return ["\n".join([e for _, e in ch.block.temps] + [e for _, e in ch.block.outputs]) for ch in fn.chunks]

    counts = {fn.name: sum(ops(code) for code in printed(fn)) for fn in functions}
    # an LU on index tables (large mechanisms) has no straight-line code to count: its
    # operations are data (its trip counts), left out of the count
    # per step's statements where there are (a rolled pass's text has a run's once)
    steps = lu.step_lines
    lu_ops = {k: sum(ops("\n".join(ls)) for ls in steps[f"{k}_chunks"]) if f"{k}_chunks" in steps
              else sum(ops("\n".join(ch["lines"])) for ch in getattr(lu, f"{k}_chunks"))
              for k in ("factor", "forward", "back", "t_forward", "t_back")}
    calls = {fn.name: sum(len(_LIBM.findall(code)) for code in printed(fn)) for fn in functions}
    worst = worst_case(counts, calls, lu_ops, f.ng, len(f.phi), len(mech.bodies), len(f.reactions))
    solve = lu_ops["forward"] + lu_ops["back"]
    # the trajectory's usual instant: one chord correction (phi, a solve),
    # phi again to test it, then the factors at the solution and the outputs
    instant = 2 * counts.get("phi", 0) + solve + counts.get("phi_q", 0) + lu_ops["factor"]
    if f.options.velocity:
        instant += counts.get("nu", 0) + counts.get("gamma", 0) + 2 * solve
    if "applied" in counts:
        instant += counts["applied"] + counts.get("mass", 0) + lu_ops["t_forward"] + lu_ops["t_back"]
    instant += counts.get("reactions", 0)
    q0 = list(model.q0)
    return Description(
        columns=[{"name": c, "string": c_string(c), "unit": unit(c)} for c in columns],
        param_info=params, unread=[p["name"] for p in params if not p["read"]],
        q0=q0, t0=a.t0, t1=a.t1, steps=a.steps, tol=a.tol,
        lit={"q0": [lit(v) for v in q0], **{k: lit(float(getattr(a, k))) for k in ("t0", "t1", "tol")}},
        ops={**counts, **{f"lu_{k}": v for k, v in lu_ops.items()}}, ops_instant=instant, worst=worst,
        body_names=[b.name for b in mech.bodies])
