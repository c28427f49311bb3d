"""Numeric backends behind one small protocol and one registry.

A backend turns a `Layout` and parameter values into an `Evaluator`, the
numeric workspace the analyses call. Adding one is: a module with a class
that has `name` and `evaluator()`, and one line in `_REGISTRY`.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import TYPE_CHECKING, Mapping, Protocol

import numpy as np

from symid.errors import InputError

if TYPE_CHECKING:  # a cached run (symid.plan) loads a backend without sympy
    import sympy as sp

    from symid.assemble import Layout

Array = np.ndarray


@dataclass(frozen=True)
class Needs:
    """What an analysis will ask of an evaluator, so nothing else is prepared.

    Attributes:
        velocity: False for statics: applied forces see qdot = 0 and no
            velocity or acceleration term is compiled.
        reactions: names of constraints whose reactions are wanted (file order).
    """

    velocity: bool = True
    reactions: tuple[str, ...] = ()


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


class Backend(Protocol):
    name: str

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs) -> Evaluator: ...


_REGISTRY = {
    "numpy": ("symid.backends.numpy_backend", "NumpyBackend"),
    "reference": ("symid.backends.reference", "ReferenceBackend"),
    "c": ("symid.backends.c_backend", "CBackend"),
    "casadi": ("symid.backends.casadi_backend", "CasadiBackend"),
}


def names() -> tuple[str, ...]:
    """The valid backend names."""
    return tuple(_REGISTRY)


def get(name: str) -> Backend:
    """The backend called `name`; an input error lists the valid ones."""
    if name not in _REGISTRY:
        raise InputError(f"--backend: unknown backend {name!r} (valid: {', '.join(_REGISTRY)})")
    module, cls = _REGISTRY[name]
    return getattr(import_module(module), cls)()
