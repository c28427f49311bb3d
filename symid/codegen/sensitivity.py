"""The parameter sensitivities of one instant as flat lists, for generated code.

Built from the per-family Jacobians of `symid.symbolic.sensitivity` (derived
once per family variant) by substituting every instance, as `flat.build`
does for the plain quantities, and multiplying by the direction: the
sensitivities already solved (`sq`, `sqd`, `sqdd`, `slam`) and the chain
from the chosen base parameters into each instance's constants and time
functions (derived parameters through their definitions). At each instant
the generated code solves, with the factors of Phi_q it already has,

    Phi_q sq = position,  Phi_q sqd = velocity,  Phi_q sqdd = acceleration,
    Phi_q^T slam = eom,   and evaluates the reactions' derivatives,

stage by stage (each right-hand side reads the stages before it).
Symbols are named as the code indexes them: `sq[k*NG + j]` is d q_j / d p_k
for the k-th chosen parameter (one vector per parameter, which the solves
take in place); `qdd[j]` the accelerations. The parameters' right-hand
sides are CSE'd together (a chunk of outputs holds several parameters), so
their common factors are computed once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import sympy as sp

from symid.codegen.flat import Options, parameter_map, vector
from symid.model.mechanism import parameter_symbol
from symid.symbolic import symbols as s
from symid.symbolic.assemble import Group, Layout
from symid.symbolic.derive import DerivedConstraint
from symid.symbolic.sensitivity import (ConstraintSensitivity, ForceSensitivity, block, parameter_chain,
                                        sensitivity_of)

# Stages in order; a column needs its own stage and every one before it.
STAGES = ("q", "qdot", "qddot", "lambda", "reactions")


@dataclass(frozen=True)
class Tangents:
    """Right-hand sides of the sensitivity stages, index `k * size + row`.

    Attributes:
        names: the chosen base parameters, the inner order of the columns.
        position, velocity, acceleration: nc * ns each (what Phi_q solves).
        eom: ng * ns (what Phi_q^T solves).
        reactions: the derivatives of `flat.reactions` (3 per role of each
            constraint in `options.reactions`), for each parameter in turn.
    """

    names: tuple[str, ...]
    position: list[sp.Expr]
    velocity: list[sp.Expr]
    acceleration: list[sp.Expr]
    eom: list[sp.Expr]
    reactions: list[sp.Expr]

    @property
    def ns(self) -> int:
        return len(self.names)


class _Replace:
    """`e.xreplace(rule)` for many e sharing subtrees, each subtree rebuilt once:
    the walk of sympy's `Basic._xreplace`, the same results."""

    def __init__(self, rule: dict[sp.Symbol, sp.Expr]) -> None:
        self.rule = rule
        self.memo: dict[sp.Basic, tuple[sp.Basic, bool]] = {}

    def __call__(self, e: sp.Basic) -> sp.Basic:
        return self._walk(e)[0]

    def _walk(self, e: sp.Basic) -> tuple[sp.Basic, bool]:
        got = self.memo.get(e)
        if got is None:
            if e in self.rule:
                got = (self.rule[e], True)
            else:
                args, changed = [], False
                for a in e.args:
                    new, moved = self._walk(a) if isinstance(a, sp.Basic) else (a, False)
                    args.append(new)
                    changed |= moved
                got = (e.func(*args), True) if changed else (e, False)
            self.memo[e] = got
        return got


def _dot(row: sp.Matrix, vec: Sequence[sp.Expr]) -> sp.Expr:
    return sp.Add(*[a * b for a, b in zip(row, vec) if a != 0 and b != 0])


class _Instance:
    """One member of a group: its local symbols substituted, its directions."""

    def __init__(self, group: Group, member: int, nb: int, ns: int, sub_base: dict[sp.Symbol, sp.Expr],
                 velocity: bool) -> None:
        self.sens = sensitivity_of(group)
        d = self.sens.derived
        self.sub: dict[sp.Symbol, sp.Expr] = dict(sub_base)
        # its Jacobians share most subtrees (the sines and cosines of its angles): each substituted
        # once, by the rule `sub` is when `part` is first called (the multipliers are added before)
        self._put = _Replace(self.sub)
        self.bodies = [int(group.bodies[role][member]) for role in d.roles]
        self.dirs: dict[str, list[list[sp.Expr]]] = {}
        for name, sym in (("q", "sq"), ("qd", "sqd"), ("qdd", "sqdd")):
            self.dirs[name] = [[sp.Integer(0) if b == nb or (name != "q" and not velocity)
                                else sp.Symbol(f"{sym}[{k * 3 * nb + 3 * b + c}]", real=True)
                                for b in self.bodies for c in range(3)] for k in range(ns)]
        for role, b in zip(d.roles, self.bodies):
            for c, (x, xd, xdd) in enumerate(zip(s.q(role), s.qd(role), s.qdd(role))):
                ground = b == nb
                self.sub[x] = sp.Integer(0) if ground else sp.Symbol(f"q[{3 * b + c}]", real=True)
                self.sub[xd] = sp.Integer(0) if ground or not velocity else sp.Symbol(f"qd[{3 * b + c}]", real=True)
                self.sub[xdd] = sp.Integer(0) if ground or not velocity else sp.Symbol(f"qdd[{3 * b + c}]", real=True)

    def part(self, matrix: sp.Matrix, which: str) -> sp.Matrix:
        """`block(matrix, ...).xreplace(self.sub)`, each shared subtree substituted once."""
        return block(matrix, self.sens, which).applyfunc(self._put)

    def tangent(self, matrix: sp.Matrix, blocks: Sequence[str], chain: dict[str, list[list[sp.Expr]]],
                k: int) -> list[sp.Expr]:
        """Each row of matrix (a Jacobian) times the direction of parameter k
        over the argument blocks named (q, qd, qdd, lam from `dirs`;
        constants, functions from `chain`)."""
        parts = [(self.part(matrix, b), (self.dirs.get(b) or chain[b])[k]) for b in blocks
                 if b in self.sens.blocks and self.sens.blocks[b]]
        return [sp.Add(*[_dot(m.row(r), vec) for m, vec in parts]) for r in range(matrix.rows)]


def tangents(layout: Layout, options: Options, names: Sequence[str]) -> Tangents:
    """The stages' right-hand sides for the base parameters `names` (in that order)."""
    mech = layout.mechanism
    ng, nc, nb, ns = layout.ng, layout.nc, layout.nb, len(names)
    base, pmap, _ = parameter_map(mech.parameters)
    to_p = {parameter_symbol(n): sp.Symbol(f"p[{k}]", real=True) for k, n in enumerate(base)}
    chain = parameter_chain(mech, layout, list(names))
    velocity = options.velocity
    lam = vector("lam", nc)
    zero = sp.Integer(0)
    position, vel, acc = [[zero] * (nc * ns) for _ in range(3)]
    eom = [zero] * (ng * ns)
    reaction_of: dict[str, list[list[sp.Expr]]] = {}
    wanted = set(options.reactions)

    def mapped(rows: Sequence[Sequence[sp.Expr]]) -> list[list[sp.Expr]]:
        """[k][i]: per parameter, the chain of each constant or function."""
        return [[sp.sympify(r[k]).xreplace(to_p) for r in rows] for k in range(ns)]

    def local(group: Group, gchain, m: int) -> tuple[_Instance, dict[str, list[list[sp.Expr]]]]:  # type: ignore[no-untyped-def]
        derived = group.derived
        sub = {c: sp.sympify(v).xreplace(pmap) for c, v in zip(derived.constants, group.constants[m])}
        functions = [sp.sympify(f).xreplace(pmap) for f in group.functions[m]]
        if group.kind == "constraint":
            from symid.model.mechanism import T

            sub.update({sym: sp.diff(functions[0], T, n) for n, sym in enumerate(derived.functions)} if functions
                       else {})
        else:
            sub.update(dict(zip(derived.functions, functions)))
        inst = _Instance(group, m, nb, ns, sub, velocity)
        return inst, {"constants": mapped(gchain.constants[m]), "functions": mapped(gchain.functions[m])}

    for group, gchain in zip(layout.constraint_groups, chain.constraint_groups):
        derived = group.derived
        assert isinstance(derived, DerivedConstraint)
        for m in range(group.size):
            inst, ch = local(group, gchain, m)
            cs = inst.sens
            assert isinstance(cs, ConstraintSensitivity)
            r0 = int(group.rows[m])
            inst.sub.update({l: lam[r0 + k] for k, l in enumerate(derived.lam)})
            inst.dirs["lam"] = [[sp.Symbol(f"slam[{k * nc + r0 + r}]", real=True) for r in range(len(derived.lam))]
                                for k in range(ns)]
            params = ("constants", "functions")
            for k in range(ns):
                for r, e in enumerate(inst.tangent(cs.phi, params, ch, k)):
                    position[k * nc + r0 + r] = -e
                if velocity:
                    for r, e in enumerate(inst.tangent(cs.velocity, ("q",) + params, ch, k)):
                        vel[k * nc + r0 + r] = -e
                    for r, e in enumerate(inst.tangent(cs.acceleration, ("q", "qd") + params, ch, k)):
                        acc[k * nc + r0 + r] = -e
                if options.multipliers:
                    for r, e in enumerate(inst.tangent(cs.eom, ("q",) + params, ch, k)):
                        b = inst.bodies[r // 3]
                        if b != nb:
                            eom[k * ng + 3 * b + r % 3] -= e
            if group.names[m] in wanted:
                per_k = [inst.tangent(cs.reactions, ("q", "lam") + ("constants", "functions"), ch, k)
                         for k in range(ns)]
                reaction_of[group.names[m]] = per_k
    if options.multipliers:
        for group, gchain in zip(layout.force_groups, chain.force_groups):
            for m in range(group.size):
                inst, ch = local(group, gchain, m)
                fs = inst.sens
                assert isinstance(fs, ForceSensitivity)
                for k in range(ns):
                    for r, e in enumerate(inst.tangent(fs.generalized, ("q", "qd", "constants", "functions"),
                                                       ch, k)):
                        b = inst.bodies[r // 3]
                        if b != nb:
                            eom[k * ng + 3 * b + r % 3] += e
        for b, body in enumerate(mech.bodies):
            masses = [sp.sympify(body.mass).xreplace(pmap)] * 2 + [sp.sympify(body.inertia).xreplace(pmap)]
            for c in range(3):
                j = 3 * b + c
                for k in range(ns):
                    if c < 2:  # the weight m g is part of Q^A
                        eom[k * ng + j] += sp.sympify(chain.weight[b][c][k]).xreplace(to_p)
                    if velocity:  # M qdd, M's own derivative and the unknown sqdd
                        eom[k * ng + j] -= (sp.sympify(chain.mass[b][c][k]).xreplace(to_p)
                                            * sp.Symbol(f"qdd[{j}]", real=True)
                                            + masses[c] * sp.Symbol(f"sqdd[{k * ng + j}]", real=True))
    reactions = [e for k in range(ns) for c in mech.constraints if c.name in reaction_of
                 for e in reaction_of[c.name][k]]
    return Tangents(tuple(names), position, vel, acc, eom, reactions)

