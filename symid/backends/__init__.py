"""Numeric backends behind one small protocol and one registry.

A backend turns a `Layout` and parameter values into an `Evaluator`, the
numeric workspace the analyses call, and declares what its solvers can do
(`Capabilities`). Adding one is: a module with a class that has `name`,
`capabilities` and `evaluator()`, and one line in `_REGISTRY`. Solvers are
built in one place, `symid.backends.prepare`.
"""

from __future__ import annotations

from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Protocol

from symid.errors import InputError
from symid.numeric.evaluator import Array, Capabilities, Evaluator, Needs
from symid.numeric.redundancy import redundancy_error
from symid.numeric.stability import FEATURES, requested

if TYPE_CHECKING:  # a cached run (symid.tools.plan) loads a backend without sympy
    import sympy as sp

    from symid.model.analysis import Analysis
    from symid.numeric.friction import FrictionModel
    from symid.symbolic.assemble import Layout


class Backend(Protocol):
    name: str
    capabilities: Capabilities

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                  friction: FrictionModel | None = None) -> Evaluator: ...


class Loader(Protocol):
    """A backend whose built solvers load again without sympy (`Capabilities.loads`)."""

    def load(self, artifact: Path, name: str, params: Mapping[str, float]) -> Evaluator: ...


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


def capabilities(name: str) -> Capabilities:
    """What the backend called `name` declares it can do (nothing is built)."""
    return get(name).capabilities


def require_support(backend_name: str, analysis: Analysis, source: str) -> None:
    """An input error when the backend lacks a feature the analysis asks for.

    A backend that runs its own loop (the compiled C solver) names what it
    lacks in `Capabilities.lacks`; the backends driven by the Python loop have everything.
    """
    missing = [f for f in requested(analysis) if f in capabilities(backend_name).lacks]
    if not missing:
        return
    key, what = FEATURES[missing[0]]
    able = [n for n in names() if missing[0] not in capabilities(n).lacks]
    raise InputError(f"{source}: [analysis] key '{key}': the {backend_name} backend does not support {what}; "
                     f"use --backend {' or '.join(able)}")


def check_redundant(layout: Layout, values: object, backend_name: str) -> None:
    """More rows than coordinates: an input error naming the dependent rows,
    unless redundant = "min_norm" on a backend that supports it."""
    mech = layout.mechanism
    if layout.nc <= layout.ng:
        return
    if mech.analysis.redundant == "min_norm":
        require_support(backend_name, mech.analysis, mech.source)
        return
    raise redundancy_error(layout, values, "redundant = \"min_norm\" solves anyway, with minimum-norm multipliers")


__all__ = ["Array", "Backend", "Capabilities", "Evaluator", "Loader", "Needs", "capabilities", "check_redundant", "get",
           "names", "require_support"]
