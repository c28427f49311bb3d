"""The mechanism: plain immutable data, no numerics and no state.

Every number of a mechanism file may be an expression of the parameters, so
values are kept as sympy expressions over parameter symbols (and `t` for the
time functions). Numeric workspaces are built from this elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, TypeAlias

import sympy as sp

from symid.model.analysis import (  # noqa: F401 (re-exported: the model's analysis table)
    DEFAULT_COND_WARN, EXTRA_OUTPUTS, JUMP_MODES, KIND_OUTPUTS, KINDS, OUTPUT_GROUPS, REDUNDANT_MODES,
    Analysis,
)
from symid.model.sizing import NONE as NO_SIZING, Sizing

GROUND = "ground"
T = sp.Symbol("t", real=True)

Value: TypeAlias = sp.Expr | tuple[sp.Expr, ...]


def parameter_symbol(name: str) -> sp.Symbol:
    """The sympy symbol that stands for parameter `name` in every expression."""
    return sp.Symbol(name, real=True)


# A body's keys that must not be negative (a zero mass or inertia is a body
# without it): the file's reader refuses them, and so does a study for each
# variant, which sets parameters without the reader (symid.study.inertials).
INERTIALS = ("mass", "inertia")


@dataclass(frozen=True)
class Body:
    """A rigid body; q = [x, y, phi] of its centre of mass.

    Attributes:
        mass, inertia: expressions of the parameters (inertia about the centre of mass).
        q0: initial guess [x, y, phi] at t0, expressions of the parameters.
    """

    name: str
    mass: sp.Expr
    inertia: sp.Expr
    q0: tuple[sp.Expr, sp.Expr, sp.Expr]


@dataclass(frozen=True)
class Element:
    """A constraint or an applied force, as written in the file.

    Attributes:
        name: unique name.
        type: the constraint or force type (a registry key).
        bodies: role -> body name ("ground" allowed), roles "i", "j", "k".
        values: key -> expression or tuple of expressions (points, vectors,
            scalars, time functions), defaults already filled in.
        options: non-numeric settings that select a variant (a coordinate name).
        friction: the joint's friction table (`symid.model.friction`), key ->
            expression of the parameters, defaults filled in; empty: none.
    """

    name: str
    type: str
    bodies: Mapping[str, str]
    values: Mapping[str, Value]
    options: Mapping[str, str] = field(default_factory=dict)
    friction: Mapping[str, sp.Expr] = field(default_factory=dict)


DRIVER_TYPES = ("relative_angle_driver", "coordinate_driver", "distance_driver", "translational_driver")


def is_driver(c: Element) -> bool:
    """A driver constraint: a built-in driver, or an expression constraint whose row has t
    (its time part f(t) split off when read: `values["f"]`)."""
    return c.type in DRIVER_TYPES or (c.type == "expression" and "f" in c.values)


@dataclass(frozen=True)
class Mechanism:
    """A whole mechanism: bodies, constraints, forces and the analysis.

    Attributes:
        parameters: name -> expression of earlier parameters, in dependency order.
        gravity: (gx, gy) expressions of the parameters.
        source: the file it came from, for messages ("<api>" when built in code).
        sizing: its drives and bearings (`symid.model.sizing`), read by `symid size` only.
    """

    name: str
    bodies: tuple[Body, ...]
    constraints: tuple[Element, ...]
    forces: tuple[Element, ...] = ()
    parameters: Mapping[str, sp.Expr] = field(default_factory=dict)
    gravity: tuple[sp.Expr, sp.Expr] = (sp.Integer(0), sp.Integer(0))
    analysis: Analysis = Analysis()
    source: str = "<api>"
    sizing: Sizing = NO_SIZING

    def body_index(self) -> dict[str, int]:
        """Body name -> index in q (ground is not a body of q)."""
        return {b.name: n for n, b in enumerate(self.bodies)}

    @property
    def chosen_reactions(self) -> tuple[str, ...]:
        """The constraints `[analysis] reactions` names (default: every one)."""
        a = self.analysis
        return a.reactions if a.reactions is not None else tuple(c.name for c in self.constraints)

    @property
    def solved_reactions(self) -> tuple[str, ...]:
        """The constraints whose reactions a run computes: the chosen ones
        when the outputs include reactions and the kind solves forces, else none."""
        a = self.analysis
        if "reactions" in a.output_groups() and a.kind != "kinematics":
            return self.chosen_reactions
        return ()

    def reaction_starts(self, wanted: set[str]) -> tuple[dict[str, int], int]:
        """Where each wanted constraint's reactions start in a reactions
        vector (file order, 3 values per body of it), and the vector's size."""
        start, offset = {}, 0
        for c in self.constraints:
            if c.name in wanted:
                start[c.name] = offset
                offset += 3 * len(c.bodies)
        return start, offset
