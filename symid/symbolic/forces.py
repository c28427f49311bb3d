"""Applied-force families, written on generic symbols like the constraints.

Each family returns, per body role, the force it applies at its point
(global components) and the torque; `symid.symbolic.derive` turns these into
generalized forces. Gravity is not a family: it acts on every body and is
added by the assembly.
"""

from __future__ import annotations

from typing import Mapping

import sympy as sp

from symid.symbolic import symbols as s
from symid.model.elements import ForceType, Key, body, function, point, scalar

Load = tuple[sp.Expr, sp.Expr, sp.Expr]


def _point_force(o: Mapping[str, str]) -> dict[str, Load]:
    return {"i": (s.scalar("Fx"), s.scalar("Fy"), sp.Integer(0))}


def _torque(o: Mapping[str, str]) -> dict[str, Load]:
    return {"i": (sp.Integer(0), sp.Integer(0), s.scalar("T"))}


def _velocity(role: str, key: str) -> sp.Matrix:
    xd, yd, phid = s.qd(role)
    return sp.Matrix([xd, yd]) + s.B(role) * s.point(key) * phid


def _spring_damper(o: Mapping[str, str]) -> dict[str, Load]:
    d = s.global_point("j", "sj") - s.global_point("i", "si")
    length = sp.sqrt((d.T * d)[0])
    u = d / length
    rate = (u.T * (_velocity("j", "sj") - _velocity("i", "si")))[0]
    k, c, l0, fa = (s.scalar(n) for n in ("k", "c", "L0", "fa"))
    tension = k * (length - l0) + c * rate + fa
    zero = sp.Integer(0)
    return {"i": (tension * u[0], tension * u[1], zero), "j": (-tension * u[0], -tension * u[1], zero)}


def _rotational_spring_damper(o: Mapping[str, str]) -> dict[str, Load]:
    theta = s.q("j")[2] - s.q("i")[2]
    rate = s.qd("j")[2] - s.qd("i")[2]
    k, c, theta0, ta = (s.scalar(n) for n in ("k", "c", "theta0", "Ta"))
    torque = k * (theta - theta0) + c * rate + ta
    zero = sp.Integer(0)
    return {"i": (zero, zero, torque), "j": (zero, zero, -torque)}


point_force = ForceType(
    name="point_force",
    keys=(body("body", role="i"), point("s"), Key("F", "function2", symbol="F")),
    points={"i": "s"},
    loads=_point_force,
)
torque = ForceType(
    name="torque",
    keys=(body("body", role="i"), function("T")),
    points={"i": None},
    loads=_torque,
)
spring_damper = ForceType(
    name="spring_damper",
    keys=(body("i"), body("j"), point("si"), point("sj"), scalar("k"), scalar("c"), scalar("L0"),
          function("fa", default=0)),
    points={"i": "si", "j": "sj"},
    loads=_spring_damper,
)
rotational_spring_damper = ForceType(
    name="rotational_spring_damper",
    keys=(body("i"), body("j"), scalar("k"), scalar("c"), scalar("theta0"), function("Ta", default=0)),
    points={"i": None, "j": None},
    loads=_rotational_spring_damper,
)

TYPES: dict[str, ForceType] = {
    f.name: f for f in (point_force, torque, spring_damper, rotational_spring_damper)
}
