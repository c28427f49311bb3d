"""Joint friction as the mechanism file states it (contract v1.1, "Joint friction").

A `revolute`, `translational` or `pin_in_slot` may carry
`friction = {mu, radius, viscous, arm, v_smooth}`; the reader fills the
defaults below into `Element.friction` (empty: no friction). What the keys
mean is derived in `symid.symbolic.friction` and solved in `symid.numeric.friction`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping

import sympy as sp

if TYPE_CHECKING:
    from symid.model.mechanism import Element

# the families whose joints can carry friction, and what their friction is
FAMILIES = {"revolute": "torque", "translational": "force", "pin_in_slot": "force"}
KEYS = ("mu", "radius", "viscous", "arm", "v_smooth")
# tanh(v / V_SMOOTH): the default smoothing speed, in the units of w or v
V_SMOOTH = 1e-4
DEFAULTS: Mapping[str, float] = {"mu": 0.0, "radius": 0.0, "viscous": 0.0, "v_smooth": V_SMOOTH}


def has_friction(element: Element) -> bool:
    """Whether a constraint carries a friction table."""
    return bool(element.friction)


def coulomb_arm(family: str, friction: Mapping[str, sp.Expr]) -> sp.Expr:
    """The factor of `N * s(v)` in the friction law: mu * radius for a pin,
    mu for a slide."""
    mu = friction["mu"]
    return mu * friction["radius"] if family == "revolute" else mu


def inverse_arm(friction: Mapping[str, sp.Expr]) -> sp.Expr:
    """1 / arm (0 without an arm: no moment term in N)."""
    arm = friction.get("arm")
    return sp.Integer(0) if arm is None else 1 / arm
