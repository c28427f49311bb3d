"""Looped C kernels: one loop over index and parameter tables per family
instance group, in place of one unrolled copy of the family's code per
instance, so that the code of a long chain does not grow with its length.

A group is split into parts by which role is ground (as the reference
evaluator splits it); a part is looped when it has at least MIN_MEMBERS
members, no time functions, and constants that are, member by member, numbers
times at most MAX_BASIS expressions of the parameters shared by the part
(`k*b`, `-a/2`, `x0 + k*b`). The family's expressions are CSE'd once per part
on loop symbols (`q[3*b0 + 2]`, `tr[2*b0]`, a constant `c1`) and printed once;
the tables say which bodies, rows, factor slots and reaction slots each
member has. What is not looped stays unrolled (`symid.codegen.emit.block`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import sympy as sp

from symid.codegen.emit import Block, CHUNK, cse, has_word
from symid.codegen.flat import Flat, parameter_map
from symid.symbolic import symbols as s
from symid.symbolic.assemble import Group, Layout
from symid.symbolic.derive import DerivedConstraint
from symid.symbolic.rounding import grouped

MIN_MEMBERS = 4   # fewer members: the unrolled copies are as short as the loop
MAX_BASIS = 3     # expressions of the parameters a member's constant may combine

Printer = Callable[[sp.Expr], str]


def _sym(name: str) -> sp.Symbol:
    return sp.Symbol(name, real=True)


@dataclass
class Part:
    """One looped part of a constraint group.

    Attributes:
        group, members: the group and the members (indices into it) looped.
        ground: the role that is ground in every member, or None.
        subs: generic symbol -> loop symbol (coordinates, rates, constants).
        trig: sin / cos of a loop angle symbol -> its `tr` entry.
        basis: the parameter expressions the varying constants combine.
        coef: per member, per varying constant, the numbers multiplying the basis.
    """

    index: int
    group: Group
    members: list[int]
    ground: str | None
    roles: tuple[str, ...]
    subs: dict[sp.Symbol, sp.Expr]
    trig: dict[sp.Expr, sp.Symbol]
    varying: list[int]
    basis: list[sp.Expr]
    coef: list[list[list[float]]]

    @property
    def derived(self) -> DerivedConstraint:
        d = self.group.derived
        assert isinstance(d, DerivedConstraint)
        return d


def _decompose(exprs: list[sp.Expr], basis: list[sp.Expr]) -> list[list[float]] | None:
    """exprs[m] = sum_i coef[m][i] * basis[i] with numbers coef (basis
    extended as needed, at most MAX_BASIS long), or None."""
    rows: list[dict[int, float]] = []
    for e in exprs:
        row: dict[int, float] = {}
        for term in sp.Add.make_args(e):
            number, rest = term.as_coeff_Mul()
            if not number.is_Number or rest.has(s.T):
                return None
            if rest not in basis:
                basis.append(rest)
            k = basis.index(rest)
            row[k] = row.get(k, 0.0) + float(number)
        rows.append(row)
    if len(basis) > MAX_BASIS:
        return None
    return [[row.get(k, 0.0) for k in range(len(basis))] for row in rows]


def parts(layout: Layout) -> list[Part]:
    """The loopable parts of the layout's constraint groups."""
    nb = layout.nb
    _, pmap, _ = parameter_map(layout.mechanism.parameters)  # base parameters p[k], derived by definition
    out: list[Part] = []
    for group in layout.constraint_groups:
        derived = group.derived
        assert isinstance(derived, DerivedConstraint)
        if derived.functions or group.size < MIN_MEMBERS:
            continue
        roles = derived.roles
        ground_of = [next((r for r in roles if int(group.bodies[r][m]) == nb), None) for m in range(group.size)]
        for ground in dict.fromkeys(ground_of):
            members = [m for m in range(group.size) if ground_of[m] == ground]
            part = _part(len(out), group, members, ground, pmap)
            if part is not None:
                out.append(part)
    return out


def _part(index: int, group: Group, members: list[int], ground: str | None,
          pmap: dict[sp.Symbol, sp.Expr]) -> Part | None:
    if len(members) < MIN_MEMBERS:
        return None
    derived = group.derived
    assert isinstance(derived, DerivedConstraint)
    roles = tuple(r for r in derived.roles if r != ground)
    subs: dict[sp.Symbol, sp.Expr] = {}
    trig: dict[sp.Expr, sp.Symbol] = {}
    for r in derived.roles:
        if r == ground:
            for c in range(3):
                subs[s.q(r)[c]] = sp.Integer(0)
                subs[s.qd(r)[c]] = sp.Integer(0)
            continue
        b = roles.index(r)
        for c in range(3):
            subs[s.q(r)[c]] = _sym(f"q[3*b{b} + {c}]")
            subs[s.qd(r)[c]] = _sym(f"qd[3*b{b} + {c}]")
        angle = subs[s.q(r)[2]]
        trig[sp.sin(angle)] = _sym(f"tr[2*b{b}]")
        trig[sp.cos(angle)] = _sym(f"tr[2*b{b} + 1]")
    varying: list[int] = []
    basis: list[sp.Expr] = []
    coef: list[list[list[float]]] = [[] for _ in members]
    for j, const in enumerate(derived.constants):
        exprs = [sp.sympify(group.constants[m][j]).xreplace(pmap) for m in members]
        if all(e == exprs[0] for e in exprs):
            subs[const] = exprs[0]
            continue
        rows = _decompose(exprs, basis)
        if rows is None:
            return None
        varying.append(j)
        subs[const] = _sym(f"c{j}")
        for k, row in enumerate(rows):
            coef[k].append(row)
    for k in range(len(members)):  # padded to the whole basis
        coef[k] = [row + [0.0] * (len(basis) - len(row)) for row in coef[k]]
    return Part(index, group, members, ground, roles, subs, trig, varying, basis, coef)


def _lam_subs(part: Part) -> dict[sp.Symbol, sp.Expr]:
    return {l: _sym(f"lam[r0 + {k}]") for k, l in enumerate(part.derived.lam)}


def _exprs(part: Part, fn: str) -> list[tuple[str, sp.Expr]]:
    """(where, expression) of one member's outputs of `fn`: `where` indexes the
    member's row (`r0 + k`), factor slot (`slot[k]`) or reaction (`rx + k`)."""
    d = part.derived
    subs = dict(part.subs)
    out: list[tuple[str, sp.Expr]] = []
    if fn in ("phi", "nu", "gamma"):
        out = [(f"r0 + {k}", e) for k, e in enumerate(getattr(d, fn))]
    elif fn == "phi_q":
        out = [(f"{k}", d.jac[r][row, c]) for k, (r, row, c) in enumerate(jac_entries(part))]
    elif fn == "reactions":
        subs.update(_lam_subs(part))
        out = [(f"rx + {k}", e) for k, e in enumerate(e for r in d.roles for e in d.reactions[r])]
    return [(w, grouped(e.xreplace(subs)).xreplace(part.trig)) for w, e in out]


def jac_entries(part: Part) -> list[tuple[str, int, int]]:
    """(role, row, coordinate) of the family's Jacobian entries that are not
    zero for this part (its constant constants substituted)."""
    d = part.derived
    return [(r, k, c) for r in part.roles for k in range(d.family.rows) for c in range(3)
            if d.jac[r][k, c].xreplace(part.subs) != 0]


@dataclass(frozen=True)
class Coverage:
    """The outputs of each function that loops write (the rest stay unrolled)."""

    rows: set[int]
    slots: set[int]
    reactions: set[int]


def tables(part: Part, flat: Flat, layout: Layout, reaction_start: dict[str, int]) -> dict[str, Any]:
    """The part's index tables: bodies, first rows, factor slots (-1: not in
    the pattern for that member) and first reaction slots (-1: not asked)."""
    g = part.group
    slot_of = {(r, c): k for k, (r, c, _) in enumerate(flat.jac)}
    entries = jac_entries(part)
    bodies, rows, slots, reac = [], [], [], []
    for m in part.members:
        b = [int(g.bodies[r][m]) for r in part.roles]
        r0 = int(g.rows[m])
        bodies += b
        rows.append(r0)
        slots += [slot_of.get((r0 + k, 3 * b[part.roles.index(r)] + c), -1) for r, k, c in entries]
        reac.append(reaction_start.get(g.names[m], -1))
    return {"bodies": bodies, "rows": rows, "slots": slots, "reactions": reac, "nroles": len(part.roles),
            "nslots": len(entries), "n": len(part.members),
            "coef": [repr(v) for m in part.coef for row in m for v in row]}


def coverage(all_tables: list[dict[str, Any]], part_list: list[Part]) -> Coverage:
    rows: set[int] = set()
    slots: set[int] = set()
    reactions: set[int] = set()
    for t, part in zip(all_tables, part_list):
        n_rows = part.derived.family.rows
        width = 3 * len(part.derived.roles)
        for r0 in t["rows"]:
            rows.update(range(r0, r0 + n_rows))
        slots.update(k for k in t["slots"] if k >= 0)
        for rx in t["reactions"]:
            if rx >= 0:
                reactions.update(range(rx, rx + width))
    return Coverage(rows, slots, reactions)


def kernel(part: Part, fn: str, printer: Printer, args: list[str], table: dict[str, Any]) -> dict[str, Any]:
    """One function's loop over a part: CSE'd once, printed once; a slot is
    tested only where some member lacks it."""
    items = _exprs(part, fn)
    temps, reduced = cse([e for _, e in items], "e")
    code = Block(tuple((str(t), printer(e)) for t, e in temps),
                 tuple((k, printer(e)) for k, e in enumerate(reduced)))
    outputs: list[dict[str, str | None]] = []
    for (where, _), (_, text) in zip(items, code.outputs):
        if fn == "phi_q":
            k, n = int(where), table["nslots"]
            gaps = any(table["slots"][m * n + k] < 0 for m in range(table["n"]))
            outputs.append({"guard": f"slot[{where}] >= 0" if gaps else None, "target": f"out[slot[{where}]]",
                            "value": text})
        elif fn == "reactions":
            outputs.append({"guard": "rx >= 0" if min(table["reactions"]) < 0 else None, "target": f"out[{where}]",
                            "value": text})
        else:
            outputs.append({"guard": None, "target": f"out[{where}]", "value": text})
    texts = [e for _, e in code.temps] + [text for _, text in code.outputs]
    used_c = [j for j in part.varying if any(has_word(t, f"c{j}") for t in texts)]
    basis = [printer(b) for b in part.basis]
    terms = {j: _terms(part, part.varying.index(j)) for j in used_c}
    texts += [basis[i] for j in used_c for i in terms[j]]
    return {"part": part.index, "temps": code.temps, "outputs": outputs, "roles": len(part.roles),
            "constants": [(j, " + ".join(_term(part, part.varying.index(j), i) for i in terms[j]) or "0.0")
                          for j in used_c],
            "basis": [(i, basis[i]) for i in sorted({i for j in used_c for i in terms[j]})],
            "unused": [a for a in args if not any(a + "[" in t or (a == "t" and has_word(t, "t")) for t in texts)
                       and a not in ("out",)],
            "rows": fn != "phi_q", "reactions": fn == "reactions"}


def _terms(part: Part, v: int) -> list[int]:
    """The basis entries varying constant v takes for some member."""
    return [i for i in range(len(part.basis)) if any(m[v][i] != 0.0 for m in part.coef)]


def _term(part: Part, v: int, i: int) -> str:
    """C for coef * basis[i] of varying constant v at member m (a basis of 1: the number alone)."""
    index = f"m * {len(part.varying) * len(part.basis)} + {v * len(part.basis) + i}"
    coef = f"L_coef[{index}]"
    return coef if part.basis[i] == 1 else f"{coef} * B{i}"


def remaining(exprs: Sequence[sp.Expr], covered: set[int], printer: Printer) -> list[Block]:
    """Unrolled blocks of the outputs no loop writes, CSE'd in chunks."""
    left = [(k, e) for k, e in enumerate(exprs) if k not in covered]
    out = []
    for i in range(0, len(left), CHUNK):
        piece = left[i:i + CHUNK]
        temps, reduced = cse([e for _, e in piece], "e")
        out.append(Block(tuple((str(t), printer(e)) for t, e in temps),
                         tuple((k, printer(e)) for (k, _), e in zip(piece, reduced))))
    return out


# Coordinates from which a mechanism's groups are looped. Measured on the
# ladder of 64 (ng 387, loaded machine): the same us per instant looped as
# unrolled, and a third less setup; the bundled examples (ng < 40) stay
# unrolled, their committed code unchanged.
LOOP_MIN = 150
LOOPED = ("phi", "phi_q", "nu", "gamma", "reactions")


class Loops:
    """The looped parts of one mechanism, their tables and what they cover."""

    def __init__(self, flat: Flat, layout: Layout, found: list[Part] | None = None) -> None:
        self.parts = found if found is not None else parts(layout)
        wanted = set(flat.options.reactions)
        start: dict[str, int] = {}
        offset = 0
        width = {name: 3 * len(g.derived.roles) for g in layout.constraint_groups for name in g.names}
        for c in layout.mechanism.constraints:
            if c.name in wanted:
                start[c.name] = offset
                offset += width[c.name]
        self.tables = [tables(p, flat, layout, start) for p in self.parts]
        for t in self.tables:
            t["reactions_used"] = bool(flat.reactions) and any(r >= 0 for r in t["reactions"])
            t["read"] = set()  # filled by kernels(): the tables a kernel kept in table form reads
        self.cover = coverage(self.tables, self.parts)

    @classmethod
    def of(cls, flat: Flat, layout: Layout, found: list[Part] | None = None) -> "Loops | None":
        """The loops of a mechanism of LOOP_MIN coordinates or more (None:
        unrolled); found: its parts, where the caller has them already."""
        if flat.ng < LOOP_MIN:
            return None
        loops = cls(flat, layout, found)
        return loops if loops.parts else None

    def covered(self, fn: str) -> set[int]:
        if fn == "phi_q":
            return self.cover.slots
        if fn == "reactions":
            return {k for k in self.cover.reactions}
        return self.cover.rows if fn in LOOPED else set()

    def kernels(self, fn: str, args: list[str], printer: Printer, real: str = "double") -> list[dict[str, Any]]:
        """Each part's kernel of fn; "run": its loop as runs of members
        with no tables read (c_loop_runs), where they repeat."""
        from symid.codegen.c.loop_runs import run_lines

        if fn not in LOOPED:
            return []
        out = []
        for p, t in zip(self.parts, self.tables):
            if fn != "reactions" or t["reactions_used"]:
                k = kernel(p, fn, printer, args, t)
                k["run"] = run_lines(p, t, k, real)
                if k["run"] is None:  # the tables this kernel reads (loop_tables.j2 emits no other)
                    t["read"] |= {"body", "row" if k["rows"] else "slot"} | (
                        {"reac"} if k["reactions"] else set()) | ({"coef"} if k["constants"] else set())
                out.append(k)
        return out
