"""Revolute joint: the points P_i and P_j coincide."""

from __future__ import annotations

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, body, point

revolute = ConstraintType(
    name="revolute",
    keys=(body("i"), body("j"), point("si"), point("sj")),
    points={"i": "si", "j": "sj"},
    rows=2,
    phi=lambda o: list(s.global_point("j", "sj") - s.global_point("i", "si")),
)

TYPES = (revolute,)
