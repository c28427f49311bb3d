"""What the C target's batch entry point `<name>_sweep` needs (templates/c/sweep.j2).

The sweep runs K parameter vectors through the generated trajectory loop and
keeps, per variant, only the figures of a design study (contract v1.1,
`symid sweep`), accumulated as the instants are solved: per driver its
largest |effort|, that instant's time, the RMS effort (trapezoidal time
average, as `symid.output.summary` computes it) and the largest |power|; per
constraint with reactions, the largest |(Fx, Fy)| on any of its bodies.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import sympy as sp

from symid.codegen.c.layout import state_size
from symid.codegen.emit import Block, block
from symid.codegen.flat import parameter_map
from symid.codegen.model import CodeModel
from symid.model.mechanism import T
from symid.symbolic.constraints import TYPES as CONSTRAINTS, family_of

# instants solved per call of the trajectory loop inside the sweep: the rows
# stay in the first-level cache while their figures are taken
SWEEP_ROWS = 32
DRIVER_FIGURES = ("effort_peak", "effort_t_peak", "effort_rms", "power_peak")


def figure_names(model: CodeModel) -> list[str]:
    """The sweep's figure columns, in the order the C code writes them."""
    return [name for d in _drivers(model) for name in d["names"]] + [r["name"] for r in _reactions(model)]


def _offset(model: CodeModel, group: str) -> int | None:
    """Where a group's values start in a trajectory row (None: not in it)."""
    f = model.flat
    sizes = {"q": f.ng, "qdot": f.ng, "qddot": f.ng, "lambda": f.nc, "reactions": len(f.reactions)}
    offset = 1
    for g in f.options.outputs:
        if g == group:
            return offset
        offset += sizes[g]
    return None


def _drivers(model: CodeModel) -> list[dict[str, Any]]:
    """Drivers whose effort the row has (it needs the multipliers)."""
    lam = _offset(model, "lambda")
    if lam is None or model.flat.options.kind == "kinematics":
        return []
    mech = model.layout.mechanism
    out = []
    for c in mech.constraints:
        if family_of(c).is_driver:
            row, rows = model.layout.row_of[c.name]
            assert rows == 1, c.name  # a driver constrains one coordinate
            out.append({"name": c.name, "lam": lam + row, "distance": c.type == "distance_driver",
                        "f": c.values["f"], "names": [f"{c.name}.{x}" for x in DRIVER_FIGURES]})
    return out


def _reactions(model: CodeModel) -> list[dict[str, Any]]:
    """Per constraint with reactions in the row: the row offsets of (Fx, Fy) of each body role."""
    start = _offset(model, "reactions")
    if start is None:
        return []
    by_name = {c.name: c for c in model.layout.mechanism.constraints}
    out, offset = [], start
    for name in model.flat.options.reactions:  # file order, 3 values per role
        roles = len(CONSTRAINTS[by_name[name].type].roles)
        out.append({"name": f"{name}.force_peak", "pairs": [offset + 3 * k for k in range(roles)]})
        offset += 3 * roles
    return out


# Past this many constraints with reactions, their peak forces are taken in a
# loop over tables instead of one written-out test per body role: a chain of
# thousands of joints otherwise gives one function of ~700 KB of branches that
# gcc compiles in minutes (the ladder of 1024: 138 s). The same operations in
# the same order: the figures are bitwise the same.
PAIR_TABLE_MIN = 64

# The squared figures (each reaction's |F|^2, each driver's sums of e^2) are
# kept in units of a per-variant power of two: 1 until a square passes
# 2^(2 SCALE_BITS) (past ~1.3e154 in double, 1.8e19 in single, a square
# overflows); from then on every value is scaled (sweep_big), the unit
# growing in steps of 2^SCALE_BITS so that the largest is at most 1, and
# every square kept takes the change, exactly. Below the threshold the
# figures are bitwise those of plain squares, at the cost of a compare per
# effort and per new force peak (the lanes: one check of their peaks a call).
# In single the sums keep room for 2^63 instants times seconds.
SCALE_BITS = {"double": 128, "single": 32}
MAX_EXPONENT = {"double": 1024, "single": 128}  # every finite value is below 2^MAX_EXPONENT


def _pair_table(reactions: list[dict[str, Any]], first_slot: int) -> dict[str, list[int]] | None:
    """Per body role (in `_reactions` order) its row offset, its figure's slot
    and 1 for a constraint's first role; None below PAIR_TABLE_MIN constraints."""
    if len(reactions) < PAIR_TABLE_MIN:
        return None
    table: dict[str, list[int]] = {"offset": [], "slot": [], "first": []}
    for k, r in enumerate(reactions):
        for i, off in enumerate(r["pairs"]):
            table["offset"].append(off)
            table["slot"].append(first_slot + k)
            table["first"].append(int(i == 0))
    return table


def work_size(model: CodeModel, solver_work: int, row_width: int) -> int:
    """Reals of workspace one thread's `<name>_sweep` needs (SWEEP_WORK), from
    the solver's own (WORK, prepared parameters included) and its row (ROW)."""
    f = model.flat
    return (solver_work + state_size(model) + SWEEP_ROWS * row_width + len(f.jac) + f.nc
            + 5 * len(_drivers(model)) + 4)


@dataclass(frozen=True)
class Sweep:
    """What templates/c/sweep.j2, sweep.h.j2 and lanes.j2 need (`sweep`).

    Attributes:
        pairs: the reactions' body roles as tables (`_pair_table`), or None.
        rows: instants per call of the trajectory loop inside the sweep.
        work: reals of one thread's workspace (SWEEP_WORK).
        guess: the initial guess from the parameters (temporaries g).
        drive: each driver's f and df/dt (temporaries d), or None.
        drivers: per driver its multiplier's row offset, distance or not, name.
        reactions: per constraint with reactions its figure name and (Fx, Fy) offsets.
        nfig: figures per variant; names: their columns.
        big2, shrink: literals of 2^(2 SCALE_BITS), the largest square kept
            in the unit 1, and 2^-SCALE_BITS, a step of the unit's root;
            steps: how many such steps bring the largest finite value to 1.
    """

    pairs: dict[str, list[int]] | None
    rows: int
    work: int
    guess: Block
    drive: Block | None
    drivers: list[dict[str, Any]]
    reactions: list[dict[str, Any]]
    nfig: int
    names: list[str]
    big2: str
    shrink: str
    steps: int


def context(model: CodeModel, printer: Callable[[sp.Expr], str], solver_work: int, row_width: int,
            lit: Callable[[float], str] = repr, precision: str = "double") -> Sweep:
    """The sweep's part of the C templates' context (lit: a literal of the real type)."""
    mech = model.layout.mechanism
    _, pmap, _ = parameter_map(mech.parameters)
    drivers = _drivers(model)
    guess = [sp.sympify(v).xreplace(pmap) for b in mech.bodies for v in b.q0]
    drive: list[sp.Expr] = []
    for d in drivers:
        f = sp.sympify(d["f"]).xreplace(pmap)
        drive += [f, sp.diff(f, T)]
    reactions = _reactions(model)
    return Sweep(
        pairs=_pair_table(reactions, 4 * len(drivers)),
        rows=SWEEP_ROWS,
        work=work_size(model, solver_work, row_width),
        guess=block(guess, printer, prefix="g"),
        drive=block(drive, printer, prefix="d") if drive else None,
        drivers=[{"lam": d["lam"], "distance": d["distance"], "name": d["name"]} for d in drivers],
        reactions=reactions,
        nfig=4 * len(drivers) + len(reactions),
        names=figure_names(model),
        big2=lit(2.0 ** (2 * SCALE_BITS[precision])),
        shrink=lit(2.0 ** -SCALE_BITS[precision]),
        steps=MAX_EXPONENT[precision] // SCALE_BITS[precision],
    )
