"""The C target's parameter sensitivities (opt-in: `--sensitivity NAME,...`).

At each solved instant, with the factors of Phi_q the instant already has
(one factorization serves every parameter), templates/c/sensitivity.j2
solves the stages of `symid.codegen.sensitivity` for the NS chosen base
parameters and writes `d(COLUMN)/d(NAME)` after the row's other columns,
columns outer and parameters inner (the contract's order). Only the stages
the chosen columns need are computed, and only the chosen reactions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import sympy as sp

from symid.codegen.c.kernels import Kernel, Make
from symid.codegen.friction import Friction
from symid.codegen.emit import CHUNK, Block, block
from symid.codegen.flat import vector
from symid.codegen.hoist import hoist
from symid.codegen.model import CodeModel
from symid.codegen.sensitivity import STAGES, tangents
from symid.errors import InputError


def column_name(column: str, parameter: str) -> str:
    """The contract's name of one sensitivity column."""
    return f"d({column})/d({parameter})"


def columns(of: Sequence[str], names: Sequence[str]) -> list[str]:
    """The sensitivity columns, columns outer and parameters inner."""
    return [column_name(c, n) for c in of for n in names]


def _sources(model: CodeModel, row_parts: list[tuple[str, str | None, int, int]],
             of: Sequence[str], fr: Friction | None) -> tuple[list[tuple[str, int]], int]:
    """Per chosen column its stage and index in that stage's vector, and the
    last stage needed (index into STAGES; a friction column needs lambda's)."""
    where = {}
    for group, source, size, offset in row_parts:  # the plain columns come first in row_columns
        for i in range(size):
            where[model.row_columns[offset + i]] = (group if source else "zero", i)
    if fr is not None and fr.columns:  # then each joint's friction and friction power
        for k, joint in enumerate(fr.joints):
            where[f"{joint['name']}.friction"] = ("friction", 2 * k)
            where[f"{joint['name']}.friction_power"] = ("friction", 2 * k + 1)
    missing = [c for c in of if c not in where]
    if missing:
        raise InputError(f"{model.layout.mechanism.source}: --sensitivity-of: no column {missing[0]!r} in the "
                         f"results (their columns are named as in the CSV header, e.g. {list(where)[0]})")
    found = [where[c] for c in of]
    last = max((STAGES.index("lambda" if g == "friction" else g) for g, _ in found if g != "zero"), default=0)
    return found, last


# per joint and parameter, what the friction kernel gives: the derivatives of
# speed, N (all but through lam), G_i, G_j, L_i, L_j (3 each), the Coulomb
# factor, the viscous coefficient and v_smooth
FRICTION_WIDTH = 17


def _plain(e: sp.Expr) -> sp.Expr:
    """e without its `Grouped` marks (a rounding order, not a function to differentiate)."""
    from symid.symbolic.rounding import Grouped

    return sp.sympify(e).replace(Grouped, lambda a: a)


def friction_tangents(model: CodeModel, fr: Friction, names: Sequence[str]) -> list[sp.Expr]:
    """The derivatives (FRICTION_WIDTH per joint, joints inner, parameters
    outer) of each joint's friction pieces by the base parameters `names`,
    along the sensitivities `sq`, `sqd` already solved: the multipliers held
    (their part is the Newton's, in sensitivity.j2)."""
    f = model.flat
    ng = f.ng
    q, qd = vector("q", ng), vector("qd", ng)
    out: list[sp.Expr] = []
    for k, name in enumerate(names):
        pk = sp.Symbol(f"p[{f.params.index(name)}]", real=True)
        sq = vector("sq", ng * (k + 1))[k * ng:]
        sqd = vector("sqd", ng * (k + 1))[k * ng:]
        for joint in fr.joints:
            fixed = joint["fixed"]
            for e in (fixed[0], joint["normal"][0], *fixed[1:16]):
                e = _plain(e)
                free = e.free_symbols
                terms = [sp.diff(e, x) * d for xs, ds in ((q, sq), (qd, sqd)) for x, d in zip(xs, ds) if x in free]
                out.append(sp.Add(*terms, sp.diff(e, pk)))
    return out


@dataclass(frozen=True)
class Sensitivity:
    """What sensitivity.j2 and sensitivity.h.j2 need (`sens`; None: not asked for).

    Attributes:
        ns, names, labels: the parameters differentiated by (labels: with their p index).
        of, ncol, columns: the columns differentiated, and the row's sensitivity columns.
        stages: the stages solved (symid.codegen.sensitivity.STAGES);
            kernels: each one's; functions: every kernel, friction's included.
        base, size, zero: the S vector's layout (per stage its start), reals, its zero.
        copies: runs (row offset, S index, count) copied into the row; direct:
            the chosen reactions' kernel writes straight into the row instead.
        prepare, npieces: the parameter-only pieces (prepared after the others).
        offset, width: where the columns start in the row and how many.
        work: reals of workspace added.
        exprs: every expression printed (the splines they read).
        friction: joint friction's part (kernel, exprs, w, adds, nf), or None.
    """

    ns: int
    names: list[str]
    labels: list[str]
    of: list[str]
    ncol: int
    copies: list[list[int]]
    direct: bool
    size: int
    zero: int
    base: dict[str, int]
    stages: list[str]
    kernels: dict[str, Kernel]
    prepare: list[Block]
    npieces: int
    offset: int
    width: int
    work: int
    columns: list[str]
    functions: list[Kernel]
    exprs: list[sp.Expr]
    friction: dict[str, Any] | None


def context(model: CodeModel, row_parts: list[tuple[str, str | None, int, int]], row_offset: int,
            np_prepared: int, make: Make, trig: dict[sp.Expr, sp.Symbol],
            printer: Callable[[sp.Expr], str], real: str, fr: Friction | None = None) -> Sensitivity | None:
    """What sensitivity.j2 needs, or None when no sensitivity was asked for.

    Args:
        row_parts: (group, source, size, offset) of the row (compose.context).
        row_offset: where the sensitivity columns start in the row.
        np_prepared: the prepared parameters before these (NP + pieces).
        make: kernels.function (kernels of bounded size, sines and cosines shared).
        fr: the joint friction's context (symid.codegen.friction), None without friction.
    """
    f = model.flat
    o = f.options
    names, of = o.sensitivity, o.sensitivity_of
    if not names:
        return None
    ns, ng, nc = len(names), f.ng, f.nc
    if not of:  # symid.output.sensitivity.choose gives the defaults
        raise InputError(f"{model.layout.mechanism.source}: --sensitivity: no columns to differentiate")
    found, last = _sources(model, row_parts, of, fr)
    tg = tangents(model.layout, o, names)
    # the chosen reactions' derivatives in the row's order (columns outer,
    # parameters inner), so that a run of reaction columns is one copy
    chosen_r = [i for g, i in found if g == "reactions"]
    nrc, nr = len(chosen_r), len(f.reactions)
    reac = [tg.reactions[k * nr + i] for i in chosen_r for k in range(ns)]
    stage_exprs = {"q": tg.position, "qdot": tg.velocity, "qddot": tg.acceleration, "lambda": tg.eom,
                   "reactions": reac}
    wanted = [st for st in STAGES[:last + 1] if o.velocity or st not in ("qdot", "qddot")]
    groups, pieces = hoist([stage_exprs[st] for st in wanted], np_prepared)
    hoisted = dict(zip(wanted, groups))
    cv = lambda name: (f"const {real} *", name)  # noqa: E731
    ct, cp = (real, "t"), cv("p")
    args = {"q": [cv("q"), ct, cp],
            "qdot": [cv("q"), cv("qd"), ct, cp, cv("sq")],
            "qddot": [cv("q"), cv("qd"), cv("qdd"), ct, cp, cv("sq"), cv("sqd")],
            "lambda": [cv("q"), cv("qd"), cv("qdd"), cv("lam"), ct, cp, cv("sq"), cv("sqd"), cv("sqdd")],
            "reactions": [cv("q"), cv("lam"), ct, cp, cv("sq"), cv("slam")]}
    kernels = {st: make(f"s_{st}", args[st], hoisted[st], trig, printer, real) for st in wanted}
    # joint friction: lam_p through the converged friction equations (sensitivity.j2)
    friction = None
    if fr is not None and "lambda" in wanted:
        fexprs = friction_tangents(model, fr, names)
        fargs = [cv("q"), cv("qd"), cv("lam"), ct, cp, cv("sq"), cv("sqd")]
        adds = []  # (index among the chosen reactions, joint, load 0..5): L_p f + L y added there
        for jk, joint in enumerate(fr.joints):
            for r in range(6 if joint["slot"] >= 0 else 0):
                if joint["slot"] + r in chosen_r:
                    adds.append((chosen_r.index(joint["slot"] + r), jk, r))
        friction = {"kernel": make("s_friction", fargs, fexprs, trig, printer, real), "exprs": fexprs,
                    "w": FRICTION_WIDTH, "adds": adds, "nf": fr.nf}
    # S: sq | sqd | sqdd (NS NG each, one vector per parameter) | slam (NS NC) | chosen reactions
    # | friction columns (2 NF NS) | a zero
    base = {"q": 0, "qdot": ng * ns, "qddot": 2 * ng * ns, "lambda": 3 * ng * ns}
    base["reactions"] = base["lambda"] + nc * ns
    base["friction"] = base["reactions"] + nrc * ns
    base["zero"] = base["friction"] + (2 * fr.nf * ns if friction else 0)
    size = {"q": ng, "qdot": ng, "qddot": ng, "lambda": nc}
    pairs = []  # (row offset, S index) of every value
    for c, (g, i) in enumerate(found):
        for k in range(ns):
            src = (base[g] if g == "zero" else base[g] + chosen_r.index(i) * ns + k if g == "reactions"
                   else base[g] + i * ns + k if g == "friction" else base[g] + k * size[g] + i)
            pairs.append((c * ns + k, src))
    copies: list[list[int]] = []  # runs (row offset, S index, count)
    for dst, src in pairs:
        if copies and src != base["zero"] and copies[-1][1] != base["zero"] \
                and copies[-1][0] + copies[-1][2] == dst and copies[-1][1] + copies[-1][2] == src:
            copies[-1][2] += 1
        else:
            copies.append([dst, src, 1])
    # the chosen columns are all the chosen reactions, in order: their kernel writes straight into out
    direct = copies == [[0, base["reactions"], nrc * ns]] and nrc > 0
    if direct:
        copies = []
    prepare = [block(pieces[k:k + CHUNK], printer, offset=np_prepared + k) for k in range(0, len(pieces), CHUNK)]
    total = base["zero"] + 1
    labels = [f"{n} (p[{f.params.index(n)}])" for n in names]
    return Sensitivity(ns=ns, names=list(names), labels=labels, of=list(of), ncol=len(of), copies=copies,
                       direct=direct, size=total, zero=base["zero"], base=base, stages=wanted, kernels=kernels,
                       prepare=prepare, npieces=len(pieces), offset=row_offset, width=len(of) * ns,
                       work=total + ns * max(ng, nc), columns=columns(of, names),
                       functions=list(kernels.values()) + ([friction["kernel"]] if friction else []),
                       exprs=[e for st in wanted for e in stage_exprs[st]] + (friction["exprs"] if friction else []),
                       friction=friction)
