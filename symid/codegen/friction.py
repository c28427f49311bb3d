"""Joint friction in the generated C solver (contract v1.1): the per-joint
expressions of `symid.symbolic.friction` substituted for each joint, and the
numbers `templates/c/friction.j2` lays out.

A mechanism without friction (or an analysis other than inverse dynamics)
gets None here, and its generated code is exactly what it was without this.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import sympy as sp

from symid.codegen.flat import Options, _role_map, parameter_map, vector
from symid.model.friction import coulomb_arm, has_friction, inverse_arm
from symid.symbolic.assemble import Layout
from symid.symbolic.friction import ARM_INV, derive_friction
from symid.symbolic.rounding import grouped

# a joint is at rest when |speed| <= REST * max(1, max |qdot|) (symid.numeric.friction.REST)
from symid.numeric.friction import MAX_ITERATIONS, REST


# Two kernels per joint: what one instant fixes (q, qd: speed, G_i, G_j, L_i,
# L_j, 3 each, the Coulomb factor, the viscous coefficient, v_smooth), and
# what each Newton iteration needs (lam: N and dN/dlambda, its rows).
FIXED = 16
# up to this many joints with friction, the NF x NF Newton system is solved
# by elimination written out at generation (no loops, no pivot search unless
# a pivot is not the largest of its column); past it, by the dense solver
UNROLLED = 4


def _terms(exprs: list[sp.Expr], first: int, base: int, lit: Callable[[float], str] = repr) -> list[tuple[int, str]]:
    """(index base + c, C value) of the entries exprs[first:first + 3] that are
    not exactly zero: a number as a literal, else the kernel's value `v[...]`,
    so that the unrolled code adds nothing for the zeros of a couple or a slide."""
    out = []
    for c in range(3):
        e = sp.sympify(exprs[first + c])
        if e.is_zero:
            continue
        out.append((base + c, lit(float(e)) if e.is_number else f"v[{first + c}]"))
    return out


def width(rows: int) -> int:
    """Values of the iteration kernel per joint: N, then dN/dlambda."""
    return 1 + rows


def joints(layout: Layout, options: Options, lit: Callable[[float], str] = repr) -> list[dict[str, Any]]:
    """Per joint with friction, file order: its expressions (in q, qd, lam, p)
    and where it sits (bodies, rows, reaction slot)."""
    mech = layout.mechanism
    nb = layout.nb
    _, pmap, _ = parameter_map(mech.parameters)  # p holds the base parameters; derived ones by definition
    q, qd, lam = vector("q", layout.ng), vector("qd", layout.ng), vector("lam", layout.nc)
    member = {name: (g, k) for g in layout.constraint_groups for k, name in enumerate(g.names)}
    slots, _ = mech.reaction_starts(set(options.reactions))
    out = []
    for c in mech.constraints:
        if not has_friction(c):
            continue
        group, m = member[c.name]
        d = derive_friction(c.type)
        derived = d.constraint
        r0, rows = layout.row_of[c.name]
        sub = _role_map(group, m, nb, q, qd)
        sub.update({k: sp.sympify(v).xreplace(pmap) for k, v in zip(derived.constants, group.constants[m])})
        sub.update({sym: lam[r0 + k] for k, sym in enumerate(derived.lam)})
        sub[ARM_INV] = sp.sympify(inverse_arm(c.friction)).xreplace(pmap)
        exprs = [d.speed, *d.generalized["i"], *d.generalized["j"], *d.loads["i"], *d.loads["j"]]
        fixed = [grouped(sp.sympify(e).xreplace(sub)) for e in exprs]
        fixed += [sp.sympify(v).xreplace(pmap) for v in (coulomb_arm(c.type, c.friction), c.friction["viscous"],
                                                         c.friction["v_smooth"])]
        normal = [grouped(sp.sympify(e).xreplace(sub)) for e in (d.normal, *d.d_normal)]
        index = mech.body_index()
        bi, bj = index.get(c.bodies["i"], -1), index.get(c.bodies["j"], -1)
        slot = slots.get(c.name, -1)
        # what the unrolled solve adds, per joint: G into the generalized
        # coordinates of its moving bodies, L into its reaction columns
        g = [*(_terms(fixed, 1, 3 * bi, lit) if bi >= 0 else []), *(_terms(fixed, 4, 3 * bj, lit) if bj >= 0 else [])]
        loads = [*_terms(fixed, 7, slot, lit), *_terms(fixed, 10, slot + 3, lit)] if slot >= 0 else []
        out.append({"name": c.name, "fixed": fixed, "normal": normal, "rows": rows, "row": r0,
                    "i": bi, "j": bj, "slot": slot, "g": dict(g), "loads": loads})
    return out


@dataclass(frozen=True)
class Friction:
    """What templates/c/friction.j2 needs (`friction`; None: no friction to solve).

    Attributes:
        nf: joints with friction; joints: per joint its expressions and place (`joints`).
        fw, nw: values per joint of the fixed and the iteration kernel (FIXED, `width`).
        fixed, normal: the kernels' expressions, joints outer (the target prints them).
        columns: whether the row has each joint's friction and friction power.
        unrolled: whether the Newton system is solved written out (nf <= UNROLLED).
        offset: where the friction columns start in the row; row_width: the row's width after them.
        max_iterations, rest: the friction Newton's cap and rest threshold (printed).
    """

    nf: int
    fw: int
    nw: int
    fixed: list[sp.Expr]
    normal: list[sp.Expr]
    joints: list[dict[str, Any]]
    columns: bool
    unrolled: bool
    offset: int
    max_iterations: int
    rest: str
    row_width: int


def context(layout: Layout, options: Options, row_width: int,
            lit: Callable[[float], str] = repr) -> Friction | None:
    """What the templates need for friction (None: none to solve). The kernels'
    expressions are `fixed` and `normal`, for the target to print as functions."""
    if options.kind != "inverse_dynamics" or not options.multipliers:
        return None
    found = joints(layout, options, lit)  # literals of the generated code's scalar type
    if not found:
        return None
    nw = max(width(j["rows"]) for j in found)
    normal: list[sp.Expr] = []
    for j in found:  # padded to a common width: one stride per joint
        normal += j["normal"] + [sp.Integer(0)] * (nw - len(j["normal"]))
    nf = len(found)
    columns = "reactions" in options.outputs
    return Friction(nf=nf, fw=FIXED, nw=nw, fixed=[e for j in found for e in j["fixed"]], normal=normal,
                    joints=found, columns=columns, unrolled=nf <= UNROLLED, offset=row_width,
                    max_iterations=MAX_ITERATIONS, rest=lit(REST),
                    row_width=row_width + (2 * nf if columns else 0))


def work(layout: Layout, options: Options) -> int:
    """Reals of workspace friction adds (0 without friction)."""
    found = joints(layout, options) if options.kind == "inverse_dynamics" and options.multipliers else []
    if not found:
        return 0
    nf, nc, ng = len(found), layout.nc, layout.ng
    nw = max(width(j["rows"]) for j in found)
    return 1 + 8 * nf + nc + ng + nf * nc + nf * (FIXED + nw) + nf * nf
