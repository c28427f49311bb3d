"""The protocol every backend's evaluator implements, and what an analysis needs of it.

The solve loop and the stability tools know backends only through this; the
registry that builds evaluators is `symid.backends`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:  # a cached run (symid.tools.plan) loads a backend without sympy
    from symid.symbolic.assemble import Layout

Array = np.ndarray


@dataclass(frozen=True)
class Needs:
    """What an analysis will ask of an evaluator, so nothing else is prepared.

    Attributes:
        velocity: False for statics: applied forces see qdot = 0 and no
            velocity or acceleration term is compiled.
        reactions: names of constraints whose reactions are wanted (file order).
        sensitivity, sensitivity_of: the run's d(COLUMN)/d(NAME) columns
            (parameters, columns), for an evaluator whose own loop computes
            them (the c backend's); the others leave them to the Python loop.
    """

    velocity: bool = True
    reactions: tuple[str, ...] = ()
    sensitivity: tuple[str, ...] = ()
    sensitivity_of: tuple[str, ...] = ()


class Evaluator(Protocol):
    """Numeric values of one mechanism's derived quantities at one instant.

    Sizes: q, qd: (ng,); results of phi, nu, gamma: (nc,); phi_q: (nc, ng);
    applied: (ng,); mass: (ng,) (the diagonal of M); reactions: (3 * roles,)
    per requested constraint, concatenated in file order.
    """

    layout: Layout

    def phi(self, q: Array, t: float) -> Array: ...
    def phi_q(self, q: Array, t: float) -> Array: ...
    def nu(self, q: Array, t: float) -> Array: ...
    def gamma(self, q: Array, qd: Array, t: float) -> Array: ...
    def applied(self, q: Array, qd: Array | None, t: float) -> Array: ...
    def mass(self) -> Array: ...
    def reactions(self, q: Array, lam: Array, t: float) -> Array: ...
