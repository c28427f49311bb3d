"""Derive, once per family and variant, everything the analyses evaluate.

From a family's `Phi` on generic symbols, sympy gives the `Phi_q` blocks of
each body role, `nu = -Phi_t`, `gamma` and the reaction on each body (the
virtual-work formula of the reference). Results are cached per
(family, variant), so the symbolic work does not grow with the number of
joints of a mechanism.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Callable, Mapping

import sympy as sp

from symid.symbolic import symbols as s
from symid.symbolic.constraints import TYPES as CONSTRAINTS
from symid.symbolic.differentiate import Differentiator
from symid.model.elements import ConstraintType, Family, ForceType
from symid.symbolic.forces import TYPES as FORCES

Variant = tuple[tuple[str, str], ...]


def constants_of(family: Family, used: set[sp.Basic], options: Variant = ()) -> tuple[sp.Symbol, ...]:
    """The per-instance constant symbols the equations `used`, in key order.

    Points and vectors give two symbols, scalars one; keys that only feed a
    `resolve` hook (a gear's radii) appear in no equation and are left out.
    Time functions are not constants: see `time_functions_of`.
    """
    out: list[sp.Symbol] = []
    for key in family.keys:
        if key.kind in ("point", "vector"):
            out.extend(s.point(key.name))
        elif key.kind == "scalar":
            out.append(s.scalar(key.symbol_name()))
    if family.shape is not None:
        # the user's expressions: their parameters (c_k), and the reaction points though no row uses them
        out.extend(family.own_constants(dict(options)))
        used = set(used) | {x for key in family.points.values() if isinstance(key, str) for x in s.point(key)}
    return tuple(c for c in out if c in used)


def time_functions_of(family: Family) -> tuple[sp.Symbol, ...]:
    """The symbols standing for the values of the family's time functions."""
    if isinstance(family, ConstraintType):
        timed = family.is_driver if family.shape is not None else any(k.kind == "function" for k in family.keys)
        return s.F_SERIES[:3] if timed else ()
    out: list[sp.Symbol] = []
    for key in family.keys:
        if key.kind == "function":
            out.append(s.scalar(key.symbol_name()))
        elif key.kind == "function2":
            out.extend(s.scalar(key.symbol_name() + c) for c in "xy")
    return tuple(out)


def total_derivative(expr: sp.Expr, roles: tuple[str, ...], by: Differentiator | None = None) -> sp.Expr:
    """d/dt of an expression of q, qdot, t and the f series (chain rule by hand).
    `by`: a Differentiator to share (its derivatives are sympy's own)."""
    d = (by or Differentiator()).diff
    expr = sp.sympify(expr)
    out = d(expr, s.T)
    for role in roles:
        for qc, qdc, qddc in zip(s.q(role), s.qd(role), s.qdd(role)):
            out += d(expr, qc) * qdc + d(expr, qdc) * qddc
    for f, fd in zip(s.F_SERIES, s.F_SERIES[1:]):
        out += d(expr, f) * fd
    return out


def reaction(jac: sp.Matrix, lam: sp.Matrix, point_key: str | None | Callable[[], sp.Matrix],
             role: str) -> sp.Matrix:
    """[Fx, Fy, T] on the body in `role`: force at its point, torque about it.

    F = -(Phi_r)^T lambda, T = ((B s')^T (Phi_r)^T - (Phi_phi)^T) lambda; s'
    is the point key's coordinates or, for a point that moves on the body,
    the expression `point_key()` gives (the moment transfer holds for any s').
    """
    phi_r = jac[:, 0:2]
    phi_phi = jac[:, 2]
    force = -phi_r.T * lam
    if point_key is None:
        torque = -(phi_phi.T * lam)[0]
    else:
        bs = s.B(role) * (point_key() if callable(point_key) else s.point(point_key))
        torque = ((bs.T * phi_r.T - phi_phi.T) * lam)[0]
        if callable(point_key):  # q in the arm: cos^2 + sin^2 left to cancel (a pitch point's 0)
            torque = sp.simplify(torque)
    return sp.Matrix([force[0], force[1], torque])


def signature(kind: str, name: str, options: Variant = ()) -> tuple[tuple[sp.Symbol, ...], tuple[sp.Symbol, ...]]:
    """(constants, time functions) of a family variant, without deriving it.

    Only Phi (or the loads) is built: enough to lay out a mechanism, so a run
    whose generated solver is cached derives nothing.
    """
    return _signature(kind, name, tuple(options))


@cache
def _signature(kind: str, name: str, options: Variant) -> tuple[tuple[sp.Symbol, ...], tuple[sp.Symbol, ...]]:
    if kind == "constraint":
        family: Family = CONSTRAINTS[name].at(dict(options))
        used = sp.Matrix(family.phi(dict(options))).free_symbols  # type: ignore[attr-defined]
    else:
        family = FORCES[name].at(dict(options))
        used = set()
        for role, load in family.loads(dict(options)).items():  # type: ignore[attr-defined]
            used |= sp.Matrix(load).free_symbols
            key = family.points[role]
            if key is not None:
                used |= set(s.point(key))
    return constants_of(family, used, options), time_functions_of(family)


@dataclass(frozen=True, eq=False)
class DerivedConstraint:
    """Everything about one constraint family variant, on generic symbols.

    Attributes:
        phi, nu, gamma: column matrices of size rows.
        jac: role -> `Phi_q` block, rows x 3 (x, y, phi of that body).
        reactions: role -> [Fx, Fy, T], linear in `lam`.
        constants: per-instance constant symbols; `functions`: f, fd, fdd or ().
    """

    family: ConstraintType
    options: Variant
    phi: sp.Matrix
    jac: Mapping[str, sp.Matrix]
    nu: sp.Matrix
    gamma: sp.Matrix
    reactions: Mapping[str, sp.Matrix]
    lam: tuple[sp.Symbol, ...]
    constants: tuple[sp.Symbol, ...]
    functions: tuple[sp.Symbol, ...]

    @property
    def roles(self) -> tuple[str, ...]:
        return self.family.roles


def derive_constraint(name: str, options: Variant = ()) -> DerivedConstraint:
    """Derive the constraint family `name` (cached per family and variant)."""
    return _derive_constraint(name, tuple(options))


@cache
def _derive_constraint(name: str, options: Variant) -> DerivedConstraint:
    family = CONSTRAINTS[name].at(dict(options))
    roles = family.roles
    phi = sp.Matrix(family.phi(dict(options)))
    by = Differentiator()  # the Jacobian and both time derivatives share subtrees
    jac = {role: by.jacobian(list(phi), s.q(role)) for role in roles}
    phi_t = sp.Matrix([total_derivative(e, (), by) for e in phi])
    second = [total_derivative(total_derivative(e, roles, by), roles, by) for e in phi]
    no_accel = {a: 0 for role in roles for a in s.qdd(role)}
    # qdd -> 0 by xreplace, one walk for all of them (subs walks once per symbol, each
    # node asking _eval_subs): the same trees for every family (tests/symbolic/test_differentiate.py)
    gamma = sp.Matrix([-e.xreplace(no_accel) for e in second])
    lam = s.lam(family.rows)
    lam_m = sp.Matrix(lam)
    reactions = {role: reaction(jac[role], lam_m, family.points[role], role) for role in roles}
    return DerivedConstraint(
        family=family,
        options=options,
        phi=phi,
        jac=jac,
        nu=(-phi_t).applyfunc(sp.expand),
        gamma=gamma.applyfunc(_tidy),
        reactions={r: m.applyfunc(_tidy) for r, m in reactions.items()},
        lam=lam,
        constants=constants_of(family, phi.free_symbols, options),
        functions=time_functions_of(family),
    )


def _tidy(expr: sp.Expr) -> sp.Expr:
    """A cheap normal form: collect the products the chain rule spread out."""
    return sp.expand(expr)


@dataclass(frozen=True, eq=False)
class DerivedForce:
    """One force family variant on generic symbols.

    Attributes:
        generalized: role -> [Q_x, Q_y, Q_phi] it adds to that body.
        loads: role -> [Fx, Fy, T] at the family's point of that body.
    """

    family: ForceType
    options: Variant
    generalized: Mapping[str, sp.Matrix]
    loads: Mapping[str, sp.Matrix]
    constants: tuple[sp.Symbol, ...]
    functions: tuple[sp.Symbol, ...]

    @property
    def roles(self) -> tuple[str, ...]:
        return self.family.roles


def derive_force(name: str, options: Variant = ()) -> DerivedForce:
    """Derive the force family `name` (cached per family and variant)."""
    return _derive_force(name, tuple(options))


@cache
def _derive_force(name: str, options: Variant) -> DerivedForce:
    family = FORCES[name].at(dict(options))
    loads = {role: sp.Matrix(v) for role, v in family.loads(dict(options)).items()}
    generalized = {}
    for role, (fx, fy, torque) in loads.items():
        key = family.points[role]
        moment = sp.Integer(0) if key is None else ((s.B(role) * s.point(key)).T * sp.Matrix([fx, fy]))[0]
        generalized[role] = sp.Matrix([fx, fy, moment + torque])
    return DerivedForce(
        family=family,
        options=options,
        generalized=generalized,
        loads=loads,
        constants=constants_of(family, set().union(*(m.free_symbols for m in generalized.values())), options),
        functions=time_functions_of(family),
    )
