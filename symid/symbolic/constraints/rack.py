"""Rack and pinion: the rack's travel is the pinion's turn times its pitch radius.

Pinion i (its axis: i's centre of mass) turns relative to rack j; the rack
slides along its direction v_j (j's frame, a unit u = A_j v_j / |v_j|):

    u^T (r_j - r_i) - r (phi_i - phi_j) - C = 0,

so a pinion turning positive drives the rack along +v_j (the rack lies on the
side of the pinion where its teeth move along +u: at r R^T u from the axis).
The reactions are reported at that pitch point, where they are the tooth
force along the rack, +-u lambda, and no couple.
"""

from __future__ import annotations

import sympy as sp

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, body, scalar, vector


def _u() -> sp.Matrix:
    v = s.vector("vj")
    return s.A("j") * v / sp.sqrt(v[0] ** 2 + v[1] ** 2)


def _pitch_arm() -> sp.Matrix:
    """The pitch point from the pinion's axis, global: r R^T u."""
    return s.scalar("r") * s.R.T * _u()


def _pitch_on(role: str) -> sp.Matrix:
    """The pitch point in the body frame of `role` (it moves on both bodies)."""
    point = s.r("i") + _pitch_arm()
    return s.A(role).T * (point - s.r(role))


rack_and_pinion = ConstraintType(
    name="rack_and_pinion",
    keys=(body("i"), body("j"), scalar("r", rule="positive"), vector("vj", rule="nonzero"),
          scalar("C", default=0)),
    points={"i": lambda: _pitch_on("i"), "j": lambda: _pitch_on("j")},
    phi=lambda o: [(_u().T * (s.r("j") - s.r("i")))[0]
                   - s.scalar("r") * (s.q("i")[2] - s.q("j")[2]) - s.scalar("C")],
)

TYPES = (rack_and_pinion,)
