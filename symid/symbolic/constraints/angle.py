"""Drivers of an angle or a coordinate: relative angle driver, coordinate driver."""

from __future__ import annotations

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, Key, body, function, scalar

relative_angle_driver = ConstraintType(
    name="relative_angle_driver",
    keys=(body("i"), body("j"), function("f"), scalar("C", default=0)),
    points={"i": None, "j": None},
    phi=lambda o: [s.q("j")[2] - s.q("i")[2] - s.scalar("C") - s.F_SERIES[0]],
    is_driver=True,
)

coordinate_driver = ConstraintType(
    name="coordinate_driver",
    keys=(body("body", role="i"), Key("coordinate", "choice", choices=s.COORDS), function("f")),
    points={"i": None},
    phi=lambda o: [s.q("i")[s.COORDS.index(o["coordinate"])] - s.F_SERIES[0]],
    is_driver=True,
)

TYPES = (relative_angle_driver, coordinate_driver)
