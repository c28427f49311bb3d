"""No number without a guarantee: an instant with a value that is not finite
(inf or NaN) stops the run, naming the element whose expression went there.

Every backend checks the outputs of each instant (a cheap test of finiteness);
only on failure is the configuration evaluated again, element by element, by
the reference backend (`culprits`), so the hot paths pay one test per instant.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from symid.numeric.evaluator import Array
from symid.errors import AnalysisError

if TYPE_CHECKING:
    from symid.symbolic.assemble import Layout

# the outputs of an instant as a message names them
SHOWN = {"q": "q", "qd": "qdot", "qdd": "qddot", "lam": "lambda", "reactions": "reactions"}


def not_finite(**arrays: Array | None) -> list[str]:
    """The names of the given arrays holding an inf or a NaN (None: absent)."""
    return [SHOWN.get(k, k) for k, v in arrays.items() if v is not None and not np.isfinite(v).all()]


def error(layout: Layout | None, what: str, t: float, q: Array | None, qd: Array | None = None,
          qdd: Array | None = None) -> AnalysisError:
    """The analysis error of an instant whose `what` is not finite."""
    loads = "lambda" in what or "reactions" in what  # kinematics alone involves no force nor mass
    return AnalysisError(f"{what} not finite (inf or NaN); {culprits(layout, q, qd, qdd, t, loads)}", t)


def culprits(layout: Layout | None, q: Array | None, qd: Array | None, qdd: Array | None, t: float,
             loads: bool = True) -> str:
    """Which elements evaluate to a non-finite value at (q, qd, t), as a
    phrase: constraints (Phi, Phi_q, nu, gamma) and, with `loads`, forces
    (their generalized force) and bodies (mass, inertia, weight, or mass
    times qddot)."""
    if layout is None:  # a planned run: the normal path reruns and names them
        return "the elements are not known here"
    if q is None or not np.isfinite(q).all():
        return "the position itself is not finite"
    from symid.numeric.evaluator import Needs
    from symid.numeric.reference import ReferenceEvaluator
    from symid.model.params import parameter_values

    mech = layout.mechanism
    try:
        ev = ReferenceEvaluator(layout, parameter_values(mech.parameters), Needs(velocity=qd is not None))
        with np.errstate(all="ignore"):
            names = ev.nonfinite_elements(q, qd if qd is not None and np.isfinite(qd).all() else None,
                                          qdd if qdd is not None and np.isfinite(qdd).all() else None, t, loads)
    except (ArithmeticError, ValueError) as exc:  # the diagnosis must never hide the failure
        return f"the elements could not be evaluated again ({exc})"
    if not names:
        return ("every element is finite there: the solve itself overflowed (Phi_q near-singular, "
                "or values beyond the range of doubles)")
    return "not finite at this instant: " + ", ".join(names)
