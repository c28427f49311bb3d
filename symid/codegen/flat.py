"""The whole mechanism as flat symbolic lists, parameters kept symbolic.

Symbols are named as the generated code indexes them (`q[3]`, `p[0]`), so a
printer needs no renaming. Built by substituting each instance into its
family's cached derivation: cost linear in the number of instances.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import sympy as sp

from symid.symbolic import symbols as s
from symid.symbolic.assemble import Group, Layout
from symid.symbolic.derive import DerivedConstraint
from symid.model.mechanism import T, parameter_symbol
from symid.model.params import base_names, is_derived
from symid.symbolic.rounding import Grouped, grouped


def vector(name: str, n: int) -> list[sp.Symbol]:
    """Symbols printed as `name[k]` (real, so sympy keeps them unconjugated)."""
    return [sp.Symbol(f"{name}[{k}]", real=True) for k in range(n)]


@dataclass(frozen=True)
class Options:
    """What the generated solver computes.

    Attributes:
        kind: inverse_dynamics, kinematics or statics (statics: no velocity terms).
        outputs: the output groups, contract order.
        reactions: constraints whose reactions are emitted, file order.
        sensitivity, sensitivity_of: `d(COLUMN)/d(NAME)` columns to add
            (symid.codegen.c.sensitivity); empty: none, the code as without.
    """

    kind: str
    outputs: tuple[str, ...]
    reactions: tuple[str, ...]
    sensitivity: tuple[str, ...] = ()  # base parameters differentiated by (C target), in column order
    sensitivity_of: tuple[str, ...] = ()  # the columns differentiated, in order

    @property
    def velocity(self) -> bool:
        return self.kind != "statics"

    @property
    def multipliers(self) -> bool:
        return self.kind != "kinematics" and ("lambda" in self.outputs or "reactions" in self.outputs)


@dataclass(frozen=True)
class Flat:
    """Every quantity of one mechanism as lists of expressions.

    params, defaults: the base parameters (the inputs `p[k]`) and their
    values; derived: (name, definition) of each derived parameter, which the
    expressions compute from `p` (they hold no symbol of their own).
    Sizes: phi, nu, gamma: nc; jac: nnz (row, col, expr) in row-major order;
    applied, mass: ng; reactions: 3 per role of each constraint in
    `options.reactions`, concatenated in file order.
    """

    name: str
    ng: int
    nc: int
    params: tuple[str, ...]
    defaults: tuple[float, ...]
    options: Options
    phi: list[sp.Expr]
    jac: list[tuple[int, int, sp.Expr]]
    nu: list[sp.Expr]
    gamma: list[sp.Expr]
    applied: list[sp.Expr]
    mass: list[sp.Expr]
    reactions: list[sp.Expr]
    derived: tuple[tuple[str, str], ...] = ()


def _role_map(group: Group, member: int, nb: int, q: Sequence[sp.Symbol], qd: Sequence[sp.Symbol] | None,
              ) -> dict[sp.Symbol, sp.Expr]:
    out: dict[sp.Symbol, sp.Expr] = {}
    for role, bodies in group.bodies.items():
        b = int(bodies[member])
        for c in range(3):
            ground = b == nb
            out[s.q(role)[c]] = sp.Integer(0) if ground else q[3 * b + c]
            out[s.qd(role)[c]] = sp.Integer(0) if ground or qd is None else qd[3 * b + c]
    return out


def _time_map(group: Group, member: int, pmap: Mapping[sp.Symbol, sp.Symbol]) -> dict[sp.Symbol, sp.Expr]:
    functions = [sp.sympify(f).xreplace(pmap) for f in group.functions[member]]
    derived = group.derived
    if isinstance(derived, DerivedConstraint):
        if not derived.functions:
            return {}
        f = functions[0]
        return {sym: sp.diff(f, T, n) for n, sym in enumerate(derived.functions)}
    return dict(zip(derived.functions, functions))


def parameter_map(parameters: Mapping[str, sp.Expr],
                  ) -> tuple[tuple[str, ...], dict[sp.Symbol, sp.Expr], list[tuple[str, str]]]:
    """How generated code sees the parameters: the base ones are its inputs
    `p[k]`; a derived one is its definition over them.

    Returns:
        the base names (p's order), parameter symbol -> its expression in p,
        and (name, definition) of every derived parameter.
    """
    names = base_names(parameters)
    p = vector("p", len(names))
    pmap: dict[sp.Symbol, sp.Expr] = {parameter_symbol(n): p[k] for k, n in enumerate(names)}
    definitions: list[tuple[str, str]] = []
    for name, definition in parameters.items():  # dependency order: what it uses is mapped
        if is_derived(definition):
            # computed from p by its definition, as one value (the reference's rounding)
            pmap[parameter_symbol(name)] = Grouped(sp.sympify(definition).xreplace(pmap))
            definitions.append((name, str(definition)))
    return names, pmap, definitions


# What a looped member's rows and reactions hold when `build` is told to leave
# them out: a name, so that printing one by mistake cannot compile.
LOOPED = sp.Symbol("symid_looped_output", real=True)


def build(layout: Layout, options: Options, defaults: Sequence[float],
          looped: frozenset[tuple[int, int]] = frozenset()) -> Flat:
    """Substitute every instance of every group into its derivation.

    defaults: the base parameters' values, in `base_names` order.
    looped: (constraint group index, member) whose Phi, nu, gamma and
    reactions a target computes in a loop of its own (the C target's looped
    kernels): left as LOOPED, their Phi_q entries built all the same (they
    make the pattern). Half of the substitution work of a long chain.
    """
    mech = layout.mechanism
    ng, nc, nb = layout.ng, layout.nc, layout.nb
    names, pmap, definitions = parameter_map(mech.parameters)
    q, lam = vector("q", ng), vector("lam", nc)
    qd = vector("qd", ng) if options.velocity else None
    phi: list[sp.Expr] = [sp.Integer(0)] * nc
    nu: list[sp.Expr] = [sp.Integer(0)] * nc
    gamma: list[sp.Expr] = [sp.Integer(0)] * nc
    jac: dict[tuple[int, int], sp.Expr] = {}
    wanted = set(options.reactions)
    reaction_of: dict[str, list[sp.Expr]] = {}
    for gi, group in enumerate(layout.constraint_groups):
        derived = group.derived
        assert isinstance(derived, DerivedConstraint)
        rows = derived.family.rows
        for m in range(group.size):
            sub = _role_map(group, m, nb, q, qd)
            sub.update({c: sp.sympify(v).xreplace(pmap) for c, v in zip(derived.constants, group.constants[m])})
            sub.update(_time_map(group, m, pmap))
            r0 = int(group.rows[m])
            skip = (gi, m) in looped
            for k in range(rows):
                if skip:
                    phi[r0 + k] = nu[r0 + k] = gamma[r0 + k] = LOOPED
                    continue
                phi[r0 + k] = derived.phi[k].xreplace(sub)
                nu[r0 + k] = derived.nu[k].xreplace(sub)
                if options.velocity:
                    gamma[r0 + k] = derived.gamma[k].xreplace(sub)
            for role in derived.roles:
                b = int(group.bodies[role][m])
                if b == nb:
                    continue
                for k in range(rows):
                    for c in range(3):
                        e = derived.jac[role][k, c].xreplace(sub)
                        if e != 0:
                            jac[(r0 + k, 3 * b + c)] = e
            if group.names[m] in wanted and skip:
                reaction_of[group.names[m]] = [LOOPED] * (3 * len(derived.roles))
            elif group.names[m] in wanted:
                sub.update({l: lam[r0 + k] for k, l in enumerate(derived.lam)})
                reaction_of[group.names[m]] = [e.xreplace(sub) for role in derived.roles
                                               for e in derived.reactions[role]]
    applied: list[sp.Expr] = [sp.Integer(0)] * ng
    mass: list[sp.Expr] = []
    gx, gy = (sp.sympify(g).xreplace(pmap) for g in mech.gravity)
    for b, body in enumerate(mech.bodies):
        m = sp.sympify(body.mass).xreplace(pmap)
        mass += [m, m, sp.sympify(body.inertia).xreplace(pmap)]
        applied[3 * b] += m * gx
        applied[3 * b + 1] += m * gy
    for group in layout.force_groups:
        derived = group.derived
        for m in range(group.size):
            sub = _role_map(group, m, nb, q, qd)
            sub.update({c: sp.sympify(v).xreplace(pmap) for c, v in zip(derived.constants, group.constants[m])})
            sub.update(_time_map(group, m, pmap))
            for role in derived.roles:
                b = int(group.bodies[role][m])
                if b == nb:
                    continue
                for c in range(3):
                    applied[3 * b + c] += derived.generalized[role][c].xreplace(sub)  # type: ignore[union-attr]
    reactions = [e for c in mech.constraints if c.name in reaction_of for e in reaction_of[c.name]]
    g = lambda exprs: [grouped(e) for e in exprs]  # noqa: E731
    return Flat(
        name=mech.name, ng=ng, nc=nc, params=names, defaults=tuple(defaults), options=options, derived=tuple(definitions),
        phi=g(phi), jac=sorted(((r, c, grouped(e)) for (r, c), e in jac.items()), key=lambda x: (x[0], x[1])),
        nu=g(nu), gamma=g(gamma), applied=g(applied), mass=mass, reactions=g(reactions),
    )
