"""Joint friction derived per family, on the generic symbols (contract v1.1).

For each family that can carry friction, from its derived reactions:

- `speed`: w = phidot_j - phidot_i (revolute) or v, the sliding speed of j's
  point relative to body i along the unit slide direction u (slides);
- `normal`: N(lambda), |F| (revolute) or |F_n| + |T| / arm (slides; the
  symbol `arm_inv` = 1 / arm, 0 without an arm), and its derivative by each
  multiplier of the joint;
- `generalized`: role -> [Q_x, Q_y, Q_phi] of a unit friction (torque +1 on j
  and -1 on i; force +u on j and -u on i, both at j's point), so that
  generalized . qdot = speed exactly: the friction power is friction * speed;
- `loads`: role -> [Fx, Fy, T] of a unit friction at the family's point of
  that body (the reaction columns' point).

The friction itself, `-(c N s(speed) + viscous speed)`, is linear in these
and in the sign s, which depends on the speed only, never on lambda; so the
solve (`symid.numeric.friction`) needs no other derivative.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Mapping

import sympy as sp

from symid.symbolic import symbols as s
from symid.symbolic.derive import DerivedConstraint, derive_constraint

ARM_INV = s.scalar("arm_inv")


def _cross(a: sp.Matrix, b: sp.Matrix) -> sp.Expr:
    """The planar cross product a x b (a scalar)."""
    return a[0] * b[1] - a[1] * b[0]


@dataclass(frozen=True, eq=False)
class DerivedFriction:
    """One friction family on generic symbols (see the module docstring)."""

    constraint: DerivedConstraint
    speed: sp.Expr
    normal: sp.Expr
    d_normal: tuple[sp.Expr, ...]
    generalized: Mapping[str, sp.Matrix]
    loads: Mapping[str, sp.Matrix]


@cache
def derive_friction(name: str) -> DerivedFriction:
    """Derive the friction of the constraint family `name` (cached)."""
    derived = derive_constraint(name)
    react_j = derived.reactions["j"]
    xi, yi, phi_i = s.q("i")
    xdi, ydi, wi = s.qd("i")
    xdj, ydj, wj = s.qd("j")
    if name == "revolute":
        speed = wj - wi
        normal = sp.sqrt(react_j[0] ** 2 + react_j[1] ** 2)
        couple = {"i": sp.Matrix([0, 0, -1]), "j": sp.Matrix([0, 0, 1])}
        generalized, loads = couple, couple
    else:
        v = s.vector("vi")
        u = s.A("i") * v / sp.sqrt(v[0] ** 2 + v[1] ** 2)
        n = s.R * u
        arm_j = s.A("j") * s.point("sj")  # j's point from j's centre
        pj = s.global_point("j", "sj")
        from_i = pj - s.r("i")  # j's point from i's centre
        vel_j = sp.Matrix([xdj, ydj]) + wj * s.R * arm_j
        vel_i = sp.Matrix([xdi, ydi]) + wi * s.R * from_i  # i's material point under j's point
        speed = (u.T * (vel_j - vel_i))[0]
        f_n = (n.T * react_j[0:2, 0])[0]
        normal = sp.Abs(f_n) + ARM_INV * sp.Abs(react_j[2])
        generalized = {"j": sp.Matrix([u[0], u[1], _cross(arm_j, u)]),
                       "i": sp.Matrix([-u[0], -u[1], -_cross(from_i, u)])}
        to_pi = pj - s.global_point("i", "si")  # the force on i acts at j's point: its moment about P_i
        loads = {"j": sp.Matrix([u[0], u[1], 0]), "i": sp.Matrix([-u[0], -u[1], -_cross(to_pi, u)])}
    d_normal = tuple(sp.diff(normal, lam) for lam in derived.lam)
    return DerivedFriction(constraint=derived, speed=speed, normal=normal, d_normal=d_normal,
                           generalized=generalized, loads=loads)
