"""The NumPy backend: the generated standalone module of the mechanism
(cached by model hash), driven by the shared Python loop."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import Mapping

import numpy as np
import sympy as sp

from symid.assemble import Layout
from symid.backends import Array, Needs
from symid.codegen.cache import cached
from symid.codegen.flat import Options


def build(layout: Layout, options: Options) -> Path:
    """The generated module's path, generating it if needed."""
    mech = layout.mechanism

    def make(folder: Path) -> None:
        from symid.codegen.model import code_model
        from symid.codegen.targets import numpy_target

        numpy_target.generate(code_model(mech, options), folder)

    return cached(mech, options, "numpy", make) / f"{mech.name}_solver.py"


def load_module(path: Path) -> ModuleType:
    """Import a generated module from its file, under a private name."""
    spec = importlib.util.spec_from_file_location(f"symid_generated_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class NumpyEvaluator:
    """Evaluator protocol over a generated NumPy module."""

    def __init__(self, layout: Layout, values: Mapping[sp.Symbol, float], options: Options) -> None:
        self.layout = layout
        self.module = load_module(build(layout, options))
        self.p = np.array([values[sp.Symbol(n, real=True)] for n in self.module.PARAMS], dtype=float)

    def phi(self, q: Array, t: float) -> Array:
        return self.module.phi(q, t, self.p)

    def phi_q(self, q: Array, t: float) -> Array:
        return self.module.phi_q(q, t, self.p)

    def nu(self, q: Array, t: float) -> Array:
        return self.module.nu(q, t, self.p)

    def gamma(self, q: Array, qd: Array, t: float) -> Array:
        return self.module.gamma(q, qd, t, self.p)

    def applied(self, q: Array, qd: Array | None, t: float) -> Array:
        return self.module.applied(q, qd, t, self.p)

    def mass(self) -> Array:
        return self.module.mass(self.p)

    def reactions(self, q: Array, lam: Array, t: float) -> Array:
        return self.module.reactions(q, lam, t, self.p)


class NumpyBackend:
    """Registry entry: the generated NumPy module."""

    name = "numpy"

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs) -> NumpyEvaluator:
        from symid.codegen.model import options_for

        return NumpyEvaluator(layout, values, options_for(layout.mechanism))
