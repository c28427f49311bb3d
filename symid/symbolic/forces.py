"""Applied-force families, written on generic symbols like the constraints.

Each family returns, per body role, the force it applies at its point
(global components) and the torque; `symid.symbolic.derive` turns these into
generalized forces. Gravity is not a family: it acts on every body and is
added by the assembly.
"""

from __future__ import annotations

from typing import Any, Mapping

import sympy as sp

from symid.symbolic import symbols as s
from symid.model.elements import ForceType, Key, body, function, point, scalar

Load = tuple[sp.Expr, sp.Expr, sp.Expr]


# A point force's or a torque's expressions may read the state of bodies (`vx(cart)`): the
# reader splits each into its terms of t (the function's value, as before) and its terms of
# the state, written here on generic symbols (options["state"]: Fx, Fy or T), the force's own
# body as role i and every other body it reads as b1, b2, ... (symid.io.state).
STATE_CONSTANT = "c_"


def state_roles(o: Mapping[str, Any]) -> int:
    """How many bodies beyond its own a force's state terms read (roles b1, b2, ...)."""
    used = {x.name for x in sp.Tuple(*o.get("state", ())).free_symbols}
    return max((k for k in range(1, len(used) + 1) if any(f"{c}_b{k}" in used for c in ("x", "y", "phi", "xd",
                                                                                       "yd", "phid"))), default=0)


def _state_shape(o: Mapping[str, Any]) -> tuple[int, tuple[sp.Symbol, ...]]:
    used = sp.Tuple(*o.get("state", ())).free_symbols
    count = sum(1 for x in used if x.name.startswith(STATE_CONSTANT))
    return state_roles(o), tuple(s.scalar(f"{STATE_CONSTANT}{k}") for k in range(count))


def _readers(o: Mapping[str, Any]) -> dict[str, Load]:
    zero = sp.Integer(0)
    return {f"b{k + 1}": (zero, zero, zero) for k in range(state_roles(o))}


def _point_force(o: Mapping[str, Any]) -> dict[str, Load]:
    fx, fy = s.scalar("Fx"), s.scalar("Fy")
    if "state" in o:
        gx, gy = o["state"]
        fx, fy = fx + gx, fy + gy
    return {"i": (fx, fy, sp.Integer(0)), **_readers(o)}


def _torque(o: Mapping[str, Any]) -> dict[str, Load]:
    torque = s.scalar("T") + (o["state"][0] if "state" in o else 0)
    return {"i": (sp.Integer(0), sp.Integer(0), torque), **_readers(o)}


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
    shape=_state_shape,
)
torque = ForceType(
    name="torque",
    keys=(body("body", role="i"), function("T")),
    points={"i": None},
    loads=_torque,
    shape=_state_shape,
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
