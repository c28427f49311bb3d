"""The mechanism: plain immutable data, no numerics and no state.

Every number of a mechanism file may be an expression of the parameters, so
values are kept as sympy expressions over parameter symbols (and `t` for the
time functions). Numeric workspaces are built from this elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import sympy as sp

GROUND = "ground"
T = sp.Symbol("t", real=True)

KINDS = ("inverse_dynamics", "kinematics", "statics")
OUTPUT_GROUPS = ("q", "qdot", "qddot", "lambda", "reactions")
KIND_OUTPUTS: Mapping[str, tuple[str, ...]] = {
    "inverse_dynamics": OUTPUT_GROUPS,
    "kinematics": ("q", "qdot", "qddot"),
    "statics": ("q", "lambda", "reactions"),
}
# Columns beyond the contract's groups, written after all of them (see
# docs/analysis-options.md); never on by default.
EXTRA_OUTPUTS = ("cond",)
REDUNDANT_MODES = ("error", "min_norm")
JUMP_MODES = ("error", "warn")
DEFAULT_COND_WARN = 1e6  # forces lose about 2 log10(cond) digits: 4 of 16 left here

Value = sp.Expr | tuple[sp.Expr, ...]


def parameter_symbol(name: str) -> sp.Symbol:
    """The sympy symbol that stands for parameter `name` in every expression."""
    return sp.Symbol(name, real=True)


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
    """

    name: str
    type: str
    bodies: Mapping[str, str]
    values: Mapping[str, Value]
    options: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Analysis:
    """What to compute and when; see the contract's `[analysis]` table."""

    kind: str = "inverse_dynamics"
    t0: float = 0.0
    t1: float = 1.0
    steps: int = 1001
    tol: float = 1e-12
    outputs: tuple[str, ...] | None = None
    reactions: tuple[str, ...] | None = None
    # numerical stability (docs/analysis-options.md); None: not set, the default applies
    cond_warn: float | None = None
    redundant: str = "error"
    assembly_jump: str = "error"

    @property
    def cond_threshold(self) -> float:
        """The condition number above which a run warns."""
        return DEFAULT_COND_WARN if self.cond_warn is None else self.cond_warn

    def extra_outputs(self) -> tuple[str, ...]:
        """The requested columns beyond the contract's groups (`cond`), in order."""
        return tuple(e for e in EXTRA_OUTPUTS if e in (self.outputs or ()))

    def output_groups(self) -> tuple[str, ...]:
        """The output groups to write, in contract order."""
        wanted = self.outputs if self.outputs is not None else KIND_OUTPUTS[self.kind]
        return tuple(g for g in OUTPUT_GROUPS if g in wanted)

    def times(self) -> "list[float]":
        """The output instants t_k = t0 + k (t1 - t0) / (steps - 1)."""
        if self.steps == 1:
            return [self.t0]
        h = (self.t1 - self.t0) / (self.steps - 1)
        return [self.t0 + k * h for k in range(self.steps)]


@dataclass(frozen=True)
class Mechanism:
    """A whole mechanism: bodies, constraints, forces and the analysis.

    Attributes:
        parameters: name -> expression of earlier parameters, in dependency order.
        gravity: (gx, gy) expressions of the parameters.
        source: the file it came from, for messages ("<api>" when built in code).
    """

    name: str
    bodies: tuple[Body, ...]
    constraints: tuple[Element, ...]
    forces: tuple[Element, ...] = ()
    parameters: Mapping[str, sp.Expr] = field(default_factory=dict)
    gravity: tuple[sp.Expr, sp.Expr] = (sp.Integer(0), sp.Integer(0))
    analysis: Analysis = Analysis()
    source: str = "<api>"

    def body_index(self) -> dict[str, int]:
        """Body name -> index in q (ground is not a body of q)."""
        return {b.name: n for n, b in enumerate(self.bodies)}
