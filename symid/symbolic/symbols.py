"""The generic symbols every constraint and force family is written in.

A family is derived once on these symbols; an instance only supplies numbers
(or parameter expressions) for them. One table of names, used by the
derivations, the printers and the claim checker alike.
"""

from __future__ import annotations

from functools import cache

import sympy as sp

ROLES = ("i", "j", "k")
COORDS = ("x", "y", "phi")
T = sp.Symbol("t", real=True)

# A driver or load function of time and its derivatives, as plain symbols so
# that the chain rule can be applied by hand in `derive.total_derivative`.
F_SERIES = tuple(sp.Symbol(n, real=True) for n in ("f", "fd", "fdd", "fddd"))


def _sym(name: str) -> sp.Symbol:
    return sp.Symbol(name, real=True)


@cache
def q(role: str) -> tuple[sp.Symbol, sp.Symbol, sp.Symbol]:
    """x_role, y_role, phi_role."""
    return tuple(_sym(f"{c}_{role}") for c in COORDS)  # type: ignore[return-value]


@cache
def qd(role: str) -> tuple[sp.Symbol, sp.Symbol, sp.Symbol]:
    """xd_role, yd_role, phid_role."""
    return tuple(_sym(f"{c}d_{role}") for c in COORDS)  # type: ignore[return-value]


@cache
def qdd(role: str) -> tuple[sp.Symbol, sp.Symbol, sp.Symbol]:
    """xdd_role, ydd_role, phidd_role."""
    return tuple(_sym(f"{c}dd_{role}") for c in COORDS)  # type: ignore[return-value]


def point(key: str) -> sp.Matrix:
    """Body coordinates of the point named by `key` ("si" -> six, siy)."""
    return sp.Matrix([_sym(key + "x"), _sym(key + "y")])


vector = point


def scalar(name: str) -> sp.Symbol:
    """A constant of a family (L, K, C, theta0, k, c, ...)."""
    return _sym(name)


def lam(rows: int) -> tuple[sp.Symbol, ...]:
    """The multipliers of a constraint: `lambda` or `lambda1, lambda2`."""
    if rows == 1:
        return (_sym("lambda"),)
    return tuple(_sym(f"lambda{n + 1}") for n in range(rows))


R = sp.Matrix([[0, -1], [1, 0]])


def rot(phi: sp.Expr) -> sp.Matrix:
    """A(phi): body to global rotation."""
    return sp.Matrix([[sp.cos(phi), -sp.sin(phi)], [sp.sin(phi), sp.cos(phi)]])


def r(role: str) -> sp.Matrix:
    """Position of the centre of mass of the body in `role`."""
    x, y, _ = q(role)
    return sp.Matrix([x, y])


def A(role: str) -> sp.Matrix:
    """Rotation matrix of the body in `role`."""
    return rot(q(role)[2])


def B(role: str) -> sp.Matrix:
    """dA/dphi = R A of the body in `role`."""
    return R * A(role)


def global_point(role: str, key: str | None) -> sp.Matrix:
    """r + A s' for the point `key` of the body in `role` (its centre if None)."""
    if key is None:
        return r(role)
    return r(role) + A(role) * point(key)
