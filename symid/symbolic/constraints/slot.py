"""Pin in slot (planar parallel-2), translational joint and slider driver.

All three measure the pin P_j of body j against the line of body i through
P_i with direction a_i = A_i v_i.
"""

from __future__ import annotations

import sympy as sp

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, body, function, point, scalar, vector

_KEYS = (body("i"), body("j"), point("si"), vector("vi"), point("sj"))
_POINTS = {"i": "si", "j": "sj"}


def _a() -> sp.Matrix:
    return s.A("i") * s.vector("vi")


def _d() -> sp.Matrix:
    return s.global_point("j", "sj") - s.global_point("i", "si")


def _off_line() -> sp.Expr:
    return (_a().T * s.R.T * _d())[0]


pin_in_slot = ConstraintType(
    name="pin_in_slot", keys=_KEYS, points=_POINTS, phi=lambda o: [_off_line()]
)

translational = ConstraintType(
    name="translational",
    keys=_KEYS + (scalar("theta0", default=0),),
    points=_POINTS,
    rows=2,
    phi=lambda o: [_off_line(), s.q("j")[2] - s.q("i")[2] - s.scalar("theta0")],
)


def _slide() -> sp.Expr:
    v = s.vector("vi")
    u = _a() / sp.sqrt(v[0] ** 2 + v[1] ** 2)
    return (u.T * _d())[0] - s.F_SERIES[0]


translational_driver = ConstraintType(
    name="translational_driver",
    keys=_KEYS + (function("f"),),
    points=_POINTS,
    phi=lambda o: [_slide()],
    is_driver=True,
)

TYPES = (pin_in_slot, translational, translational_driver)
