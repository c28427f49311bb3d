"""Sensitivity derivation: what the exact derivatives of a solved instant with
respect to base parameters need, derived once per family variant.

The instant is the solution of four sets of equations (reference formulas):

    Phi(q, t)                                 = 0    (position)
    Phi_q qd - nu                             = 0    (velocity)
    Phi_q qdd - gamma(q, qd)                  = 0    (acceleration)
    M qdd + Phi_q^T lam - Q^A(q, qd)          = 0    (equations of motion)

and the reactions R(q, lam) are explicit. Each family (constraint or force) is
written on local arguments: the coordinates of its bodies `q`, their rates
`qd`, `qdd`, its per-instance constants `c`, its time-function values `f`
(constraints: f, f', f''), its multipliers `lam`. Differentiating each
residual with respect to all its local arguments once, the parameter
derivative of everything follows by the chain rule through the instance's
constants and time functions (`parameter_chain`), one column per parameter:

    Phi_q q_p   = -(Phi_c c_p + Phi_f f_p)
    Phi_q qd_p  = -(V_q q_p + V_c c_p + V_f f_p)                 V = Phi_q qd - nu
    Phi_q qdd_p = -(A_q q_p + A_qd qd_p + A_c c_p + A_f f_p)     A = Phi_q qdd - gamma
    Phi_q^T lam_p = -(E_q q_p + E_c c_p + E_f f_p + M_p qdd + M qdd_p
                      - Q_q q_p - Q_qd qd_p - Q_c c_p - Q_f f_p - (m g)_p)   E = Phi_q^T lam
    R_p = R_q q_p + R_c c_p + R_f f_p + R_lam lam_p

The column blocks of each Jacobian below are exactly the pieces named in
issue #15: `block(sens.velocity, "q")` is (Phi_q qd)_q - nu_q,
`block(sens.acceleration, "qd")` is -gamma_qd, `block(sens.eom, "q")` is
(Phi_q^T lam)_q, `block(sens.phi, "constants")` is Phi_c, and so on.

Public functions (read by the generated-C sensitivities too):

- `constraint_sensitivity(name, options) -> ConstraintSensitivity` (cached):
  `args` (the local argument symbols, in `ARG_BLOCKS` order), and the
  Jacobians `phi` (rows x nargs), `velocity` (rows x nargs), `acceleration`
  (rows x nargs), `eom` (3 roles x nargs: the rows of Phi_q^T lam on each
  role's x, y, phi), `reactions` (3 roles x nargs, as `DerivedConstraint.reactions`).
- `force_sensitivity(name, options) -> ForceSensitivity` (cached): `args`
  and `generalized` (3 roles x nargs), the Jacobian of Q^A's contributions.
- `block(matrix, sens, which)`: the columns of one argument block.
- `expand_derived(expr, parameters)`: an expression with every derived
  parameter replaced by its definition (recursively), so it is a function of
  base parameters only.
- `parameter_chain(mechanism, layout, names) -> Chain`: per group and member,
  d(constants)/d(p) and d(time functions)/d(p) as expressions (of the
  parameters; time functions also of t), and per body d(mass)/d(p),
  d(inertia)/d(p), and d(gravity)/d(p), for the base parameters `names`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, cached_property
from typing import Mapping, Sequence

import sympy as sp

from symid.model.mechanism import T, Mechanism, parameter_symbol
from symid.symbolic import symbols as s
from symid.symbolic.assemble import Group, Layout
from symid.symbolic.differentiate import Differentiator
from symid.symbolic.derive import (DerivedConstraint, DerivedForce, Variant, derive_constraint, derive_force, reaction,
                                   total_derivative)

# Local argument blocks of a family, in this order (forces have no qdd, lam).
ARG_BLOCKS = ("q", "qd", "qdd", "constants", "functions", "lam")


def _blocks(derived: DerivedConstraint | DerivedForce) -> dict[str, tuple[sp.Symbol, ...]]:
    roles = derived.roles
    out: dict[str, tuple[sp.Symbol, ...]] = {
        "q": tuple(x for r in roles for x in s.q(r)),
        "qd": tuple(x for r in roles for x in s.qd(r)),
    }
    if isinstance(derived, DerivedConstraint):
        out["qdd"] = tuple(x for r in roles for x in s.qdd(r))
    out["constants"] = derived.constants
    out["functions"] = derived.functions
    if isinstance(derived, DerivedConstraint):
        out["lam"] = derived.lam
    return out


@dataclass(frozen=True, eq=False)
class ConstraintSensitivity:
    """Jacobians of one constraint family variant's residuals by its local arguments.

    Each Jacobian is derived on first use (statics needs no `velocity` nor
    `acceleration`, kinematics no `eom` nor `reactions`), then kept.

    Attributes:
        derived: the family's derivation.
        blocks: block name -> its symbols (`ARG_BLOCKS` order); `args` all of them.
        phi, velocity, acceleration: rows x nargs.
        eom, reactions: (3 * roles) x nargs, role by role as `derived.roles`.
    """

    derived: DerivedConstraint
    blocks: Mapping[str, tuple[sp.Symbol, ...]]

    @property
    def args(self) -> tuple[sp.Symbol, ...]:
        return tuple(x for b in self.blocks.values() for x in b)

    @cached_property
    def _by(self) -> Differentiator:
        """One memo for all five Jacobians: their rows share most subtrees."""
        return Differentiator()

    @cached_property
    def _first(self) -> list[sp.Expr]:
        # V = Phi_q qd - nu and A = Phi_q qdd - gamma are the first and second total
        # time derivatives of Phi: differentiated in that compact form (not the
        # expanded gamma), sympy's diff is several times faster.
        return [total_derivative(e, self.derived.roles, self._by) for e in self.derived.phi]

    @cached_property
    def phi(self) -> sp.Matrix:
        return _jacobian(list(self.derived.phi), self.args, self._by)

    @cached_property
    def velocity(self) -> sp.Matrix:
        return _jacobian(self._first, self.args, self._by)

    @cached_property
    def acceleration(self) -> sp.Matrix:
        by = self._by
        return _jacobian([total_derivative(e, self.derived.roles, by) for e in self._first], self.args, by)

    @cached_property
    def eom(self) -> sp.Matrix:
        d = self.derived
        lam = sp.Matrix(d.lam)
        return _jacobian([e for r in d.roles for e in d.jac[r].T * lam], self.args, self._by)

    @cached_property
    def reactions(self) -> sp.Matrix:
        d = self.derived
        lam = sp.Matrix(d.lam)
        return _jacobian([e for r in d.roles for e in reaction(d.jac[r], lam, d.family.points[r], r)], self.args,
                         self._by)


@dataclass(frozen=True, eq=False)
class ForceSensitivity:
    """The Jacobian of one force family variant's generalized forces.

    Attributes:
        blocks: block name -> symbols ("q", "qd", "constants", "functions").
        generalized: (3 * roles) x nargs.
    """

    derived: DerivedForce
    blocks: Mapping[str, tuple[sp.Symbol, ...]]
    generalized: sp.Matrix

    @property
    def args(self) -> tuple[sp.Symbol, ...]:
        return tuple(x for b in self.blocks.values() for x in b)


def block(matrix: sp.Matrix, sens: ConstraintSensitivity | ForceSensitivity, which: str) -> sp.Matrix:
    """The columns of `matrix` (one of `sens`'s Jacobians) for the argument block `which`."""
    start = 0
    for name, symbols in sens.blocks.items():
        if name == which:
            return matrix[:, start:start + len(symbols)]
        start += len(symbols)
    raise KeyError(which)


def _jacobian(exprs: Sequence[sp.Expr], args: Sequence[sp.Symbol], by: Differentiator | None = None) -> sp.Matrix:
    """`Matrix(exprs).jacobian(args)`, element for element (`Differentiator`: the
    same expressions, each shared subtree's derivative built once)."""
    return (by or Differentiator()).jacobian(exprs, args)


def constraint_sensitivity(name: str, options: Variant = ()) -> ConstraintSensitivity:
    """Derive the residual Jacobians of constraint family `name` (cached per variant)."""
    return _constraint(name, tuple(options))


@cache
def _constraint(name: str, options: Variant) -> ConstraintSensitivity:
    d = derive_constraint(name, options)
    return ConstraintSensitivity(derived=d, blocks=_blocks(d))


def force_sensitivity(name: str, options: Variant = ()) -> ForceSensitivity:
    """Derive the generalized-force Jacobian of force family `name` (cached per variant)."""
    return _force(name, tuple(options))


@cache
def _force(name: str, options: Variant) -> ForceSensitivity:
    d = derive_force(name, options)
    blocks = _blocks(d)
    args = [x for b in blocks.values() for x in b]
    generalized = [e for r in d.roles for e in d.generalized[r]]
    jac = _jacobian(generalized, args)
    if jac.has(sp.DiracDelta):  # sign(v)'s derivative: 0 but at the kink, where no derivative is exact
        jac = jac.applyfunc(lambda e: e.replace(sp.DiracDelta, lambda *a: sp.Integer(0)))
    return ForceSensitivity(derived=d, blocks=blocks, generalized=jac)


def sensitivity_of(group: Group) -> ConstraintSensitivity | ForceSensitivity:
    """The family sensitivity of a layout group."""
    if group.kind == "constraint":
        return constraint_sensitivity(group.family, group.variant)
    return force_sensitivity(group.family, group.variant)


def expand_derived(expr: sp.Expr, parameters: Mapping[str, sp.Expr]) -> sp.Expr:
    """`expr` with every derived parameter replaced by its definition, recursively,
    so that it depends on base parameters (and t) only."""
    definitions = {parameter_symbol(n): sp.sympify(e) for n, e in parameters.items() if sp.sympify(e).free_symbols}
    out = sp.sympify(expr)
    for _ in range(len(definitions) + 1):  # each pass resolves one level of definitions
        if not out.free_symbols & definitions.keys():
            return out
        out = out.xreplace(definitions)
    return out


@dataclass(frozen=True)
class GroupChain:
    """Per member of one group, derivatives by the chosen base parameters.

    Attributes:
        constants: [member][constant][parameter], expressions of the parameters.
        functions: [member][function][parameter], expressions of t and the
            parameters (constraints: f, f', f'' of the member's f).
    """

    constants: tuple[tuple[tuple[sp.Expr, ...], ...], ...]
    functions: tuple[tuple[tuple[sp.Expr, ...], ...], ...]


@dataclass(frozen=True)
class Chain:
    """d(everything an instance is built from)/d(base parameters `names`).

    Attributes:
        constraint_groups, force_groups: as the layout's groups.
        mass: [body][x, y, phi][parameter], the mass diagonal's derivatives.
        weight: [body][x, y][parameter], d(m g)/dp.
    """

    names: tuple[str, ...]
    constraint_groups: tuple[GroupChain, ...]
    force_groups: tuple[GroupChain, ...]
    mass: tuple[tuple[tuple[sp.Expr, ...], ...], ...]
    weight: tuple[tuple[tuple[sp.Expr, ...], ...], ...]


def _d(expr: sp.Expr, parameters: Mapping[str, sp.Expr], names: Sequence[str]) -> tuple[sp.Expr, ...]:
    full = expand_derived(expr, parameters)
    return tuple(sp.diff(full, parameter_symbol(n)) for n in names)


def _group_chain(group: Group, parameters: Mapping[str, sp.Expr], names: Sequence[str]) -> GroupChain:
    constants = tuple(tuple(_d(c, parameters, names) for c in member) for member in group.constants)
    functions = []
    for member in group.functions:
        if group.kind == "constraint" and member:
            series = [sp.diff(member[0], T, order) for order in range(3)]  # f, f', f''
        else:
            series = list(member)
        functions.append(tuple(_d(f, parameters, names) for f in series))
    return GroupChain(constants, tuple(functions))


def parameter_chain(mechanism: Mechanism, layout: Layout, names: Sequence[str]) -> Chain:
    """The chain from base parameters `names` into every instance's constants,
    time functions, masses and weights (derived parameters through their
    definitions: a parameter `n` moves `omega = 2*pi*n`)."""
    params = mechanism.parameters
    mass = tuple((_d(b.mass, params, names), _d(b.mass, params, names), _d(b.inertia, params, names))
                 for b in mechanism.bodies)
    weight = tuple(tuple(_d(b.mass * g, params, names) for g in mechanism.gravity) for b in mechanism.bodies)
    return Chain(
        names=tuple(names),
        constraint_groups=tuple(_group_chain(g, params, names) for g in layout.constraint_groups),
        force_groups=tuple(_group_chain(g, params, names) for g in layout.force_groups),
        mass=mass,
        weight=weight,
    )
