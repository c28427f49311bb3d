"""Mechanism -> system: the layout of rows and columns, grouped by family.

Instances of one family variant form a group that is evaluated together
(vectorized, or by one generated routine), so a mechanism's size costs only
numbers, never more symbolic work. Nothing here depends on a backend.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from symid.symbolic.constraints import TYPES as CONSTRAINTS, family_of
from symid.symbolic.derive import DerivedConstraint, DerivedForce, derive_constraint, derive_force, signature
from symid.model.elements import ConstraintType, Family
from symid.symbolic.forces import TYPES as FORCES
from symid.model.mechanism import GROUND, Element, Mechanism
from symid.symbolic import symbols as s


@dataclass(frozen=True)
class Group:
    """The instances of one derived family variant.

    Attributes:
        derived: the symbolic derivation shared by all members.
        members: indices of the members in the mechanism's constraints (or forces).
        names: their names.
        bodies: role -> body index per member, shape (n,); ground is index nb.
        rows: first constraint row of each member, shape (n,) (forces: unused).
        constants: per member, the expressions (of parameters) for `derived.constants`.
        functions: per member, the time-function expressions for `derived.functions`
            (constraints: f only; its derivatives are derived from it).
    """

    kind: str
    family: str
    variant: tuple[tuple[str, str], ...]
    members: tuple[int, ...]
    names: tuple[str, ...]
    bodies: Mapping[str, np.ndarray]
    rows: np.ndarray
    constants: tuple[tuple[sp.Expr, ...], ...]
    functions: tuple[tuple[sp.Expr, ...], ...]

    @property
    def size(self) -> int:
        return len(self.members)

    @property
    def derived(self) -> DerivedConstraint | DerivedForce:
        """The family's derivation, made on first use (and cached per family):
        laying out a mechanism whose solver is already generated derives nothing."""
        if self.kind == "constraint":
            return derive_constraint(self.family, self.variant)
        return derive_force(self.family, self.variant)

    @property
    def roles(self) -> tuple[str, ...]:
        return tuple(self.bodies)


@dataclass(frozen=True)
class Layout:
    """Where everything of a mechanism sits in q, Phi and the results.

    Attributes:
        ng, nc: number of coordinates (3 per body) and of constraint rows.
        row_of: constraint name -> (first row, number of rows).
        constraint_groups, force_groups: the groups, in first-appearance order.
    """

    mechanism: Mechanism
    ng: int
    nc: int
    row_of: Mapping[str, tuple[int, int]]
    constraint_groups: tuple[Group, ...]
    force_groups: tuple[Group, ...]

    @property
    def nb(self) -> int:
        return self.ng // 3

    @cached_property
    def values(self) -> dict[sp.Symbol, float]:
        """Every parameter's value (derived ones by their definitions), computed once."""
        from symid.model.params import parameter_values

        return parameter_values(self.mechanism.parameters)

    @cached_property
    def q0(self) -> np.ndarray:
        """The initial guess at those values, size ng, computed once (read-only: copy to change it)."""
        from symid.model.params import initial_guess

        q0 = initial_guess(self.mechanism, self.values)
        q0.flags.writeable = False
        return q0

    def constraint_names_of_rows(self, rows: Sequence[int] | np.ndarray) -> list[str]:
        """The constraints that own the given rows, without repeats, in row order."""
        out: list[str] = []
        for row in rows:
            for name, (start, n) in self.row_of.items():
                if start <= row < start + n and name not in out:
                    out.append(name)
        return out


def _element_values(family: Family, derived_constants: tuple[sp.Symbol, ...], element: Element,
                    ) -> tuple[sp.Expr, ...]:
    """The values of the derived constant symbols for one element."""
    by_symbol: dict[sp.Symbol, sp.Expr] = {}
    # the parameters of the user's own expressions (an expression constraint, a force of the state)
    by_symbol.update(zip(family.own_constants(element.options), element.values.get("constants", ())))
    for key in family.keys:
        value = element.values.get(key.name)
        if key.kind in ("point", "vector"):
            by_symbol.update(zip(s.point(key.name), value))  # type: ignore[arg-type, call-overload]
        elif key.kind == "scalar" and value is not None:
            by_symbol[s.scalar(key.symbol_name())] = value  # type: ignore[assignment]
    return tuple(sp.sympify(by_symbol[c]) for c in derived_constants)


def _element_functions(family: Family, element: Element) -> tuple[sp.Expr, ...]:
    if isinstance(family, ConstraintType) and family.shape is not None:  # a driver row's f(t), split off
        return (element.values["f"],) if "f" in element.values else ()  # type: ignore[return-value]
    out: list[sp.Expr] = []
    for key in family.keys:
        if key.kind == "function":
            out.append(element.values[key.name])  # type: ignore[arg-type]
        elif key.kind == "function2":
            out.extend(element.values[key.name])  # type: ignore[arg-type]
    return tuple(out)


def _groups(elements: tuple[Element, ...], registry: Mapping[str, Family], kind: str,
            body_index: Mapping[str, int], starts: list[int]) -> tuple[Group, ...]:
    keyed: dict[tuple[str, tuple[tuple[str, str], ...]], list[int]] = {}
    for n, element in enumerate(elements):
        variant = registry[element.type].variant(element.options)
        keyed.setdefault((element.type, variant), []).append(n)
    groups = []
    for (name, variant), members in keyed.items():
        family = registry[name].at(dict(variant))  # type: ignore[attr-defined]
        constants, _ = signature(kind, name, variant)
        bodies = {role: np.array([body_index[elements[m].bodies[role]] for m in members], dtype=np.intp)
                  for role in family.roles}
        groups.append(Group(
            kind=kind,
            family=name,
            variant=variant,
            members=tuple(members),
            names=tuple(elements[m].name for m in members),
            bodies=bodies,
            rows=np.array([starts[m] for m in members], dtype=np.intp),
            constants=tuple(_element_values(family, constants, elements[m]) for m in members),
            functions=tuple(_element_functions(family, elements[m]) for m in members),
        ))
    return tuple(groups)


def assemble(mech: Mechanism) -> Layout:
    """Lay out a mechanism: rows, columns and groups. Cost linear in its size."""
    body_index = {**mech.body_index(), GROUND: len(mech.bodies)}
    starts: list[int] = []
    row_of: dict[str, tuple[int, int]] = {}
    row = 0
    for c in mech.constraints:
        rows = family_of(c).rows
        starts.append(row)
        row_of[c.name] = (row, rows)
        row += rows
    return Layout(
        mechanism=mech,
        ng=3 * len(mech.bodies),
        nc=row,
        row_of=row_of,
        constraint_groups=_groups(mech.constraints, CONSTRAINTS, "constraint", body_index, starts),
        force_groups=_groups(mech.forces, FORCES, "force", body_index, [0] * len(mech.forces)),
    )


def reaction_columns(layout: Layout, names: tuple[str, ...] | None) -> list[tuple[str, str]]:
    """(constraint, column) pairs of the requested reactions, in file order.

    A constraint has Fx, Fy, T for each of its body roles: `C.Fx_i` etc.
    """
    wanted = set(names) if names is not None else None
    out: list[tuple[str, str]] = []
    for c in layout.mechanism.constraints:
        if wanted is not None and c.name not in wanted:
            continue
        for role in CONSTRAINTS[c.type].roles:
            out.extend((c.name, f"{c.name}.{comp}_{role}") for comp in ("Fx", "Fy", "T"))
    return out
