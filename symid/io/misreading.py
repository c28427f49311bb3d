"""Warnings for inputs that are valid but probably not what was meant.

Angles are radians; a magnitude above 2 pi is legal (angles are never
wrapped) but is far more often degrees written by habit, which silently
gives another mechanism. A driver's angle formula is read the same way: its
value at t0, and its rate there when that is above 2 pi rad/s and a whole
multiple of 15 ("270*t", "90*t", "360*t"): the steps of a rate written in
degrees per second. A rate in rad/s above a turn a second is common, but
comes from 2 pi n, a measured speed or a round 10, 20, 50, 100 (which pass). And Newton assembles the mechanism at t0 from the
`q0` guesses: a body that ends far from its guess may have been assembled in
another mode than the one drawn.
"""

from __future__ import annotations

import math
from typing import Iterator, Mapping

import numpy as np
import sympy as sp

from symid.model.mechanism import T, Mechanism
from symid.model.params import parameter_values, to_float
from symid.text import number

TURN = 2 * math.pi
FAR_ANGLE = 1.0  # rad: a guess is rough, but a body turned further than this is in another pose
FAR_SHIFT = 0.5  # of the mechanism's size (the spread of the q0 positions, ground's origin included)


def _angles(mech: Mechanism, values: Mapping[sp.Symbol, float]) -> Iterator[tuple[str, sp.Expr]]:
    """(where, expression) of every value the file gives in radians, at t0."""
    t0 = mech.analysis.t0
    for b in mech.bodies:
        yield f"body '{b.name}' key 'q0' (phi)", b.q0[2]
    for section, elements in (("constraint", mech.constraints), ("force", mech.forces)):
        for e in elements:
            where = f"{section} '{e.name}' key"
            if e.type in ("translational", "rotational_spring_damper"):
                yield f"{where} 'theta0'", e.values["theta0"]
            if e.type == "relative_angle_driver" or (e.type == "coordinate_driver"
                                                      and e.options.get("coordinate") == "phi"):
                yield f"{where} 'f' at t0 = {number(t0)}", sp.sympify(e.values["f"]).subs(T, t0)
            if e.type == "relative_angle_driver":
                yield f"{where} 'C'", e.values.get("C", sp.Integer(0))


def _rates(mech: Mechanism) -> Iterator[tuple[str, sp.Expr]]:
    """(where, df/dt at t0) of every angle driver's formula."""
    t0 = mech.analysis.t0
    for e in mech.constraints:
        if e.type == "relative_angle_driver" or (e.type == "coordinate_driver"
                                                  and e.options.get("coordinate") == "phi"):
            try:
                rate = sp.diff(sp.sympify(e.values["f"]), T).subs(T, t0)
            except (TypeError, ValueError, sp.SympifyError):  # a tabled f: its values are read elsewhere
                continue
            yield f"constraint '{e.name}' key 'f': its rate at t0 = {number(t0)}", rate


DEGREE_STEP = 15  # degrees per second as people write them: 15, 30, 45, 90, 180, 270, 360, 720


def _in_degrees(value: float) -> bool:
    """A rate above 2 pi whose value is a whole multiple of DEGREE_STEP."""
    steps = value / DEGREE_STEP
    return abs(value) > TURN and abs(steps - round(steps)) <= 1e-9 * abs(steps)


def angle_warnings(mech: Mechanism) -> list[str]:
    """One line per angle above 2 pi in magnitude ("did you mean degrees?")."""
    values = parameter_values(mech.parameters)
    out = []
    for where, expr in _angles(mech, values):
        try:
            value = to_float(expr, values)
        except (ValueError, TypeError):  # a tabled f is checked where it is read
            continue
        if abs(value) > TURN:
            out.append(f"{mech.source}: {where} = {number(value)} is more than 2 pi: radians expected; "
                       f"did you mean {number(value)} degrees ({number(math.radians(value))} rad)?")
    for where, expr in _rates(mech):
        try:
            value = to_float(expr, values)
        except (ValueError, TypeError):
            continue
        if _in_degrees(value):
            out.append(f"{mech.source}: {where} = {number(value)} rad/s, a multiple of {DEGREE_STEP} above 2 pi: "
                       f"radians per second expected; did you mean {number(value)} degrees per second "
                       f"({number(math.radians(value))} rad/s)?")
    return out


def assembly_warnings(mech: Mechanism, q0: np.ndarray, q: np.ndarray) -> list[str]:
    """One line per body that Newton assembled at t0 far from its q0 guess.

    Args:
        q0: the guesses, size ng; q: the assembled coordinates at t0, size ng.
    """
    points = np.vstack([np.zeros(2), q0.reshape(-1, 3)[:, :2]])
    size = max(float(np.max(np.linalg.norm(points[:, None] - points[None], axis=-1))), 1e-300)
    out = []
    for b, guess, got in zip(mech.bodies, q0.reshape(-1, 3), q.reshape(-1, 3)):
        shift, turn = float(np.hypot(*(got[:2] - guess[:2]))), abs(float(got[2] - guess[2]))
        if shift > FAR_SHIFT * size or turn > FAR_ANGLE:
            out.append(f"{mech.source}: body '{b.name}' was assembled at t0 = {number(mech.analysis.t0)} far from "
                       f"its q0: [{', '.join(number(v) for v in got)}] instead of "
                       f"[{', '.join(number(v) for v in guess)}]; if that is not the intended pose, "
                       f"give a closer q0 (angles in radians)")
    return out
