"""Rolling bearings' rating life from a run's joint loads (ISO 281's
variable-load method).

Over the run, a revolute carries |F| (its reaction) while its bodies turn
relative to each other at theta_dot = omega_j - omega_i. The equivalent load
weights each instant by the relative rotation it turns through:

    P_eq = ( int |F|^p |theta_dot| dt / int |theta_dot| dt )^(1/p)

and the L10 life is (C / P_eq)^p million revolutions, in hours at the run's
mean relative speed int |theta_dot| dt / (t1 - t0). A joint that oscillates
counts the angle it sweeps back and forth (its own relative angle, not the
crank's turns). The integrals are trapezoidal over the run's instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from symid.errors import InputError
from symid.model.mechanism import GROUND, Element
from symid.model.sizing import Bearing
from symid.output.sizing.motor import weights


@dataclass(frozen=True)
class Life:
    """One bearing's equivalent load [N] and L10 life [h] (JSON: `joint`, `P_eq`, `L10_h`).

    Attributes:
        C, p: its rating [N] and exponent; speed: mean relative speed [rad/s].
    """

    joint: str
    C: float
    p: float
    P_eq: float
    L10_h: float
    speed: float

    def json(self) -> dict[str, object]:
        return {"joint": self.joint, "P_eq": self.P_eq, "L10_h": self.L10_h}

    def line(self) -> str:
        return (f"{self.joint}: equivalent load {self.P_eq:.4g} N (C {self.C:.4g} N, p {self.p:.4g}), "
                f"L10 {self.L10_h:.4g} h at {self.speed * 30 / math.pi:.4g} rpm relative")


def life(bearing: Bearing, joint: Element, table: object, values: Mapping[object, float], source: str) -> Life:
    """The bearing's life from a results table with the joint's reactions and the bodies' omega."""
    from symid.model.params import to_float

    C, p = to_float(bearing.C, values), to_float(bearing.p, values)  # type: ignore[arg-type]
    get = table.__getitem__  # type: ignore[attr-defined]
    t = np.asarray(get("t"), dtype=float)
    force = np.hypot(get(f"{joint.name}.Fx_j"), get(f"{joint.name}.Fy_j"))
    rate = np.zeros(len(t))
    for role, sign in (("j", 1.0), ("i", -1.0)):
        if joint.bodies[role] != GROUND:
            rate = rate + sign * np.asarray(get(f"{joint.bodies[role]}.omega"), dtype=float)
    w = weights(t) * np.abs(rate)
    turned = float(np.sum(w))  # mean |theta_dot| over the run, rad/s
    if not turned > 0:
        raise InputError(f"{source}: constraint '{joint.name}' key 'bearing': the joint does not rotate "
                         "in this run (its bodies keep their relative angle): no rating life")
    top = float(np.max(force))
    P = top * float(np.sum(w * (force / top) ** p) / turned) ** (1 / p) if top > 0 else 0.0
    revolutions = (C / P) ** p * 1e6 if P > 0 else math.inf
    hours = revolutions * 2 * math.pi / turned / 3600
    return Life(joint.name, C, p, P, hours, turned)
