"""Show derivations readably: Unicode (`sympy.pretty`), LaTeX, and in Jupyter.

`derive_type(name)` shows one constraint family on the generic symbols of
`docs/symbols.md`; `derive_mechanism(mech)` the assembled system of a whole
mechanism. Both return a `Derivation`, whose `text()` is Unicode, `latex()`
is LaTeX and which Jupyter displays as LaTeX (`_repr_latex_`).

A family is shown in the hand notation of the notes: global vectors
s_i = A_i s'_i, a_i = A_i v'_i, d = d_ij and its rate replace body-frame
components and the coordinates of body j. That is a change of variables, not
an approximation: substituting the definitions back gives the derivation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Mapping

import sympy as sp
from sympy.printing.pretty.stringpict import prettyForm

from symid.symbolic import symbols as s
from symid.symbolic.constraints import TYPES as CONSTRAINTS
from symid.symbolic.derive import DerivedConstraint, derive_constraint
from symid.model.elements import registry_lookup
from symid.errors import InputError
from symid.symbolic.assemble import assemble
from symid.model.mechanism import GROUND, Mechanism
from symid.tools.notation import SUBSCRIPT, Pretty, pretty, latex, scalar

GEAR_NOTE = "gear rows relate angles only: the tooth force at the pitch point is not represented"


def with_functions(expr: sp.Basic) -> sp.Basic:
    """The plain driver symbols f, fd, fdd as f(t) and its derivatives."""
    f = sp.Function("f", real=True)(s.T)
    return expr.xreplace({a: sp.diff(f, s.T, n) for n, a in enumerate(s.F_SERIES)})


def tidy(expr: sp.Expr) -> sp.Expr:
    """A small readable normal form: expand, cos^2 + sin^2 = 1, common factors out.

    No trigsimp: on a mechanism's rows it costs seconds and rarely shortens them.
    """
    expr = sp.expand(expr, power_exp=False)
    angles = {a.args[0] for a in expr.atoms(sp.sin)}
    expr = sp.expand(expr.subs({sp.sin(a) ** 2: 1 - sp.cos(a) ** 2 for a in angles}), power_exp=False)
    expr = sp.factor_terms(expr)
    factored = sp.factor(expr) if expr.is_polynomial() and sp.count_ops(expr) < 200 else expr
    return factored if sp.count_ops(factored) < sp.count_ops(expr) else expr


# -- what is shown -----------------------------------------------------------------

@dataclass(frozen=True)
class Item:
    """One displayed equation `label = value` (or prerendered text and LaTeX)."""

    label: str
    tex_label: str
    value: sp.Basic | None = None
    text: str | None = None
    tex: str | None = None

    def render_text(self) -> str:
        if self.value is None:
            return f"{self.label}\n{self.text}"
        form = Pretty({"use_unicode": True})._print(scalar(self.value))
        return prettyForm(*prettyForm(self.label + " = ").right(form)).render(wrap_line=False)

    def render_tex(self) -> str:
        body = self.tex if self.value is None else latex(self.value)
        return rf"{self.tex_label} &= {body}"


@dataclass(frozen=True)
class Derivation:
    """A derivation to show: a title, `where` definitions, equations and notes."""

    title: str
    items: tuple[Item, ...]
    where: tuple[tuple[str, str], ...] = ()
    notes: tuple[str, ...] = field(default=())
    tex_title: str | None = None  # LaTeX for the title when it holds symbols

    def text(self) -> str:
        parts = [self.title]
        if self.where:
            parts.append("where " + "; ".join(u for u, _ in self.where))
        parts += [item.render_text() for item in self.items]
        parts += [f"note: {n}" for n in self.notes]
        return "\n\n".join(parts) + "\n"

    def latex(self) -> str:
        rows = [self.tex_title or rf"&\text{{{_tex_text(self.title)}}}"]
        if self.where:
            rows.append(r"&\text{where } " + r",\quad ".join(t for _, t in self.where))
        rows += [item.render_tex() for item in self.items]
        rows += [rf"&\text{{note: {_tex_text(n)}}}" for n in self.notes]
        return "\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"

    def __str__(self) -> str:
        return self.text()

    def _repr_latex_(self) -> str:
        return "$$\n" + self.latex() + "\n$$"


def _tex_text(text: str) -> str:
    return re.sub(r"([_&%#$])", r"\\\1", text)


# -- one constraint family -------------------------------------------------------

def _abbreviations(der: DerivedConstraint) -> tuple[dict[sp.Symbol, sp.Expr], list[tuple[str, str]]]:
    """Body-frame components -> global vectors, and x_j, y_j (rates) -> d (d-dot)."""
    sym = lambda n: sp.Symbol(n, real=True)  # noqa: E731
    subs: dict[sp.Symbol, sp.Expr] = {}
    where: list[tuple[str, str]] = []
    glob: dict[str, tuple[sp.Symbol, sp.Symbol]] = {}
    used = der.phi.free_symbols
    for key in (k for k in der.family.keys if k.kind in ("point", "vector")):
        bx, by = s.point(key.name)
        if bx not in used and by not in used:
            continue
        role, name = key.name[1], "s" if key.kind == "point" else "a"
        gx, gy = glob[key.name] = (sym(f"_{name}_{role}x"), sym(f"_{name}_{role}y"))
        c, sn = sp.cos(s.q(role)[2]), sp.sin(s.q(role)[2])
        subs.update({bx: c * gx + sn * gy, by: -sn * gx + c * gy})
        src = "s" if name == "s" else "v"
        where.append((f"{name}{SUBSCRIPT[role]} = A{SUBSCRIPT[role]} {src}\u2032{SUBSCRIPT[role]}",
                      f"{name}_{{{role}}} = A_{{{role}}} {src}'_{{{role}}}"))
    if "si" in glob and "sj" in glob:
        (six, siy), (sjx, sjy) = glob["si"], glob["sj"]
        (xi, yi, _), (xdi, ydi, pdi), pdj = s.q("i"), s.qd("i"), s.qd("j")[2]
        dx, dy, ddx, ddy = (sym(n) for n in ("_d_x", "_d_y", "_dd_x", "_dd_y"))
        xj, yj, _ = s.q("j")
        xdj, ydj, _ = s.qd("j")
        subs.update({xj: dx + xi + six - sjx, yj: dy + yi + siy - sjy,
                     xdj: ddx + xdi - siy * pdi + sjy * pdj, ydj: ddy + ydi + six * pdi - sjx * pdj})
        where.append(("d = r\u2c7c + s\u2c7c - r\u1d62 - s\u1d62 and its rate \u1e0b",
                      r"d = r_{j} + s_{j} - r_{i} - s_{i} \text{ and its rate } \dot{d}"))
    return subs, where


def abbreviate(expr: sp.Basic, subs: Mapping[sp.Symbol, sp.Expr]) -> sp.Basic:
    """`expr` in the display variables (exact change of variables), tidied."""
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(lambda e: abbreviate(e, subs))
    return tidy(expr.xreplace(dict(subs)))


def check_options(name: str, options: Mapping[str, str]) -> None:
    """Refuse an option the type has no variant choice for (it would be ignored, silently).

    Raises:
        InputError: naming the option and the type's own options (or that it has none).
    """
    family = CONSTRAINTS.get(name)
    if family is None:
        return  # derive_type names the unknown type
    own = [key.name for key in family.keys if key.kind == "choice"]
    for key in options:
        if key not in own:
            has = f"its options: {', '.join(own)}" if own else "it has no variant options"
            raise InputError(f"derive {name}: option {key!r} does not apply to {name} ({has})")


def derive_type(name: str, options: Mapping[str, str] | None = None, expanded: bool = False) -> Derivation:
    """Phi, the Phi_q blocks, nu, gamma and the reactions of one constraint type.

    Args:
        name: a constraint type (`symid.symbolic.constraints.TYPES`).
        options: its variant choices (coordinate_driver: coordinate = x, y or phi).
        expanded: show body-frame components instead of the hand notation.
    """
    try:
        family = registry_lookup(CONSTRAINTS, name, "constraint type")
    except LookupError as exc:
        raise InputError(str(exc)) from None
    options = dict(options or {})
    check_options(name, options)
    for key in family.keys:
        if key.kind == "choice" and options.get(key.name) not in key.choices:
            raise InputError(f"{name}: option '{key.name}' must be one of {', '.join(key.choices)}")
    der = derive_constraint(name, family.variant(options))
    subs, where = ({}, []) if expanded else _abbreviations(der)
    show = lambda e: abbreviate(e, subs)  # noqa: E731
    items = [Item("\u03a6", r"\Phi", show(der.phi))]
    for role in der.roles:
        sub = SUBSCRIPT[role]
        items.append(Item(f"\u03a6_q{sub} = [\u03a6_r{sub} | \u03a6_\u03c6{sub}]",
                          rf"\Phi_{{\mathbf{{q}}_{{{role}}}}}", show(der.jac[role])))
    items += [Item("\u03bd = -\u03a6_t", r"\nu", show(der.nu)), Item("\u03b3", r"\gamma", show(der.gamma))]
    for role in der.roles:
        react = show(der.reactions[role])
        at = der.family.points[role]
        where_at = ("at the pitch point" if callable(at)  # a point moving on the body: the rack's only
                    else f"at P{SUBSCRIPT[role]}" if at else "at the centre of mass")
        items.append(Item(f"F_on_{role} ({where_at})", rf"F_{{\text{{on }}{role}}}", react[:2, :]))
        items.append(Item(f"T_on_{role}", rf"T_{{\text{{on }}{role}}}", react[2]))
    notes = [GEAR_NOTE] if name.startswith("gear") else []
    rows = f"{len(der.lam)} row{'s' if len(der.lam) > 1 else ''}"
    variant = "".join(f" ({k} = {v})" for k, v in options.items())
    title = f"{name}{variant}: {rows}, multiplier{'s' if len(der.lam) > 1 else ''} "
    tex_title = rf"&\text{{{_tex_text(title)}}}" + ", ".join(latex(x) for x in der.lam)
    title += ", ".join(pretty(x) for x in der.lam)
    return Derivation(title, tuple(items), tuple(where), tuple(notes), tex_title)


# -- a whole mechanism ----------------------------------------------------------

@dataclass(frozen=True)
class MechanismSystem:
    """A mechanism's equations on its own symbols, parameters kept symbolic.

    Body b has coordinates x_b, y_b, phi_b and rates xd_b, yd_b, phid_b.

    Attributes:
        coords: q, size ng. rows: constraint -> (first row, number of rows).
        phi, nu, gamma: constraint -> column of its rows (tables in row order).
        blocks: constraint -> body -> its Phi_q block (rows x 3); ground has none.
        reactions: constraint -> role -> [Fx, Fy, T], linear in the multipliers
            `lambda` (or `lambda1, lambda2`) of that constraint.
        applied: body -> Q^A of the body (3); mass: body -> [m, J].
    """

    mechanism: Mechanism
    coords: tuple[sp.Symbol, ...]
    rows: Mapping[str, tuple[int, int]]
    phi: Mapping[str, sp.Matrix]
    nu: Mapping[str, sp.Matrix]
    gamma: Mapping[str, sp.Matrix]
    blocks: Mapping[str, Mapping[str, sp.Matrix]]
    reactions: Mapping[str, Mapping[str, sp.Matrix]]
    applied: Mapping[str, sp.Matrix]
    mass: Mapping[str, tuple[sp.Expr, sp.Expr]]

    @property
    def ng(self) -> int:
        return len(self.coords)

    @property
    def nc(self) -> int:
        return sum(n for _, n in self.rows.values())

    def phi_q(self) -> sp.Matrix:
        """The assembled Phi_q, nc x ng."""
        out = sp.zeros(self.nc, self.ng)
        column = {b.name: 3 * n for n, b in enumerate(self.mechanism.bodies)}
        for c, (start, n) in self.rows.items():
            for body, block in self.blocks[c].items():
                out[start:start + n, column[body]:column[body] + 3] = block
        return out


def mechanism_system(mech: Mechanism) -> MechanismSystem:
    """Substitute every instance into its family's derivation (no new derivation)."""
    layout = assemble(mech)
    sym = lambda n: sp.Symbol(n, real=True)  # noqa: E731
    q = {b.name: tuple(sym(f"{c}_{b.name}") for c in s.COORDS) for b in mech.bodies}
    qd = {b.name: tuple(sym(f"{c}d_{b.name}") for c in s.COORDS) for b in mech.bodies}
    q[GROUND] = qd[GROUND] = (sp.Integer(0),) * 3
    phi, nu, gamma, blocks, reactions = {}, {}, {}, {}, {}
    applied = {b.name: sp.Matrix([b.mass * mech.gravity[0], b.mass * mech.gravity[1], 0]) for b in mech.bodies}
    for group in layout.constraint_groups + layout.force_groups:
        der = group.derived
        elements = mech.constraints if isinstance(der, DerivedConstraint) else mech.forces
        for n, m in enumerate(group.members):
            el = elements[m]
            sub = dict(zip(der.constants, group.constants[n]))
            for role in der.roles:
                sub.update({**dict(zip(s.q(role), q[el.bodies[role]])), **dict(zip(s.qd(role), qd[el.bodies[role]]))})
            if isinstance(der, DerivedConstraint):
                if der.functions:
                    sub.update({a: sp.diff(group.functions[n][0], s.T, k) for k, a in enumerate(der.functions)})
                phi[el.name], nu[el.name], gamma[el.name] = (e.xreplace(sub) for e in (der.phi, der.nu, der.gamma))
                blocks[el.name] = {el.bodies[r]: der.jac[r].xreplace(sub) for r in der.roles
                                   if el.bodies[r] != GROUND}
                reactions[el.name] = {r: der.reactions[r].xreplace(sub) for r in der.roles}
                continue
            sub.update(zip(der.functions, group.functions[n]))
            for role in der.roles:
                if el.bodies[role] != GROUND:
                    applied[el.bodies[role]] += der.generalized[role].xreplace(sub)
    order = lambda table: {c.name: table[c.name] for c in mech.constraints}  # noqa: E731 (row order)
    return MechanismSystem(mech, tuple(x for b in mech.bodies for x in q[b.name]), dict(layout.row_of),
                           order(phi), order(nu), order(gamma), order(blocks), order(reactions), applied,
                           {b.name: (b.mass, b.inertia) for b in mech.bodies})


def _block_map(sysm: MechanismSystem, names: Mapping[tuple[str, str], int]) -> tuple[str, str]:
    """Phi_q's block structure: a text table of block numbers, and the LaTeX matrix."""
    bodies = [b.name for b in sysm.mechanism.bodies]
    table = [["", "rows"] + bodies]
    tex_rows: list[str] = []
    for c, (start, n) in sysm.rows.items():
        table.append([c, f"{start + 1}-{start + n}" if n > 1 else str(start + 1)]
                     + [f"B{names[c, b]}" if (c, b) in names else "\u00b7" for b in bodies])
        cells = [sysm.blocks[c].get(b, sp.zeros(n, 3)) for b in bodies]
        if tex_rows:
            tex_rows.append(r"\hline")
        tex_rows += [" & ".join(latex(tidy(blk[r, k])) for blk in cells for k in range(3)) + r" \\"
                     for r in range(n)]
    widths = [max(len(row[k]) for row in table) for k in range(len(table[0]))]
    text = "\n".join("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in table)
    tex = (r"\left[\begin{array}{" + "|".join(["ccc"] * len(bodies)) + "}\n"
           + "\n".join(tex_rows) + "\n\\end{array}\\right]")
    return text, tex


def derive_mechanism(mech: Mechanism | str) -> Derivation:
    """The assembled Phi_q (its block structure visible), Phi, gamma, Q^A and M.

    Args:
        mech: a `Mechanism` or the path of a mechanism file.
    """
    from symid.io.reader import load

    mechanism = mech if isinstance(mech, Mechanism) else load(mech)
    sysm = mechanism_system(mechanism)
    names: dict[tuple[str, str], int] = {}
    for c in sysm.rows:
        for b in (b.name for b in mechanism.bodies if b.name in sysm.blocks[c]):
            names[c, b] = len(names) + 1
    block_text, block_tex = _block_map(sysm, names)
    name = lambda n: r"\mathrm{" + _tex_text(n) + "}"  # noqa: E731
    items = [Item("q", r"\mathbf{q}", sp.Matrix(sysm.coords).T),
             Item(f"\u03a6_q ({sysm.nc} x {sysm.ng}; rows: constraints, columns: bodies, \u00b7 zero)",
                  r"\Phi_{\mathbf{q}}", text=block_text, tex=block_tex)]
    items += [Item(f"B{n} = \u03a6_q[{c}, {b}]", rf"\Phi_{{\mathbf{{q}}}}[{name(c)}, {name(b)}]",
                   sysm.blocks[c][b].applyfunc(tidy)) for (c, b), n in names.items()]
    for label, tex, table in (("\u03a6", r"\Phi", sysm.phi), ("\u03b3", r"\gamma", sysm.gamma)):
        items += [Item(f"{label}[{c}]", rf"{tex}[{name(c)}]", table[c].applyfunc(tidy)) for c in sysm.rows]
    items += [Item(f"Q^A[{b}]", rf"Q^{{A}}[{name(b)}]", v.applyfunc(tidy).T) for b, v in sysm.applied.items()]
    items += [Item(f"diag M[{b}]", rf"\operatorname{{diag}} M[{name(b)}]", sp.Matrix([[m, m, j]]))
              for b, (m, j) in sysm.mass.items()]
    notes = []
    if any(c.type.startswith("gear") for c in mechanism.constraints):
        notes.append(GEAR_NOTE)
    rough = [c.name for c in mechanism.constraints if c.friction]
    if rough:  # it depends on the reactions, so it is in no formula above; say so, not leave it out silently
        notes.append(f"joint friction ({', '.join(rough)}) is not in Q^A: it depends on the joints' reactions "
                     f"and is solved with them at each instant (docs/friction.md, symid help friction)")
    return Derivation(f"mechanism {mechanism.name}: ng = {sysm.ng}, nc = {sysm.nc}", tuple(items),
                      notes=tuple(notes))
