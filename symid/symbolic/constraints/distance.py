"""Distance between two points: a massless link (constant) or a cylinder (driven)."""

from __future__ import annotations

import sympy as sp

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, body, function, point, scalar


def _d() -> sp.Matrix:
    return s.global_point("j", "sj") - s.global_point("i", "si")


revolute_revolute = ConstraintType(
    name="revolute_revolute",
    keys=(body("i"), body("j"), point("si"), point("sj"), scalar("length", symbol="L")),
    points={"i": "si", "j": "sj"},
    phi=lambda o: [(_d().T * _d())[0] - s.scalar("L") ** 2],
)

distance_driver = ConstraintType(
    name="distance_driver",
    keys=(body("i"), body("j"), point("si"), point("sj"), function("f")),
    points={"i": "si", "j": "sj"},
    phi=lambda o: [(_d().T * _d())[0] - s.F_SERIES[0] ** 2],
    is_driver=True,
)

TYPES = (revolute_revolute, distance_driver)
