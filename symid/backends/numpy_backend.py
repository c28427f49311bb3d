"""The NumPy backend: the generated standalone module of the mechanism
(cached by model hash), driven by the shared Python loop."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Mapping

import numpy as np

from symid.backends import Array, Needs

if TYPE_CHECKING:  # a cached run (symid.plan) loads a generated module without sympy
    import sympy as sp

    from symid.assemble import Layout
    from symid.codegen.flat import Options


def build(layout: Layout, options: Options) -> Path:
    """The generated module's path, generating it if needed."""
    from symid.codegen.cache import cached

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
    """Evaluator protocol over a generated NumPy module.

    Args:
        path: the generated module (`build`).
        params: parameter name -> value, for every parameter of the module.
        layout: the mechanism's layout, which names constraints in failure
            messages; None for a cached run (`symid.plan`), which reruns
            the whole normal path on any failure.
    """

    layout: Layout  # None only in a planned run, which never reads it (see above)

    def __init__(self, path: Path, params: Mapping[str, float], layout: Layout | None) -> None:
        self.layout = layout  # type: ignore[assignment]
        self.artifact = path
        self.module = load_module(path)
        self.p = np.array([params[n] for n in self.module.PARAMS], dtype=float)
        self.p_list = self.p.tolist()

    # One instant at a time, the module's scalar (`math`) kernels are an order
    # of magnitude faster than its vectorized ones on arrays of one column.
    def phi(self, q: Array, t: float) -> Array:
        return np.array(self.module._phi_s(q.tolist(), t, self.p_list))

    def phi_q(self, q: Array, t: float) -> Array:
        out = np.zeros((self.module.NC, self.module.NG))
        out[self.module.PHI_Q_ROWS, self.module.PHI_Q_COLS] = self.module._phi_q_values_s(q.tolist(), t, self.p_list)
        return out

    def nu(self, q: Array, t: float) -> Array:
        return np.array(self.module._nu_s(q.tolist(), t, self.p_list))

    def gamma(self, q: Array, qd: Array, t: float) -> Array:
        return np.array(self.module._gamma_s(q.tolist(), qd.tolist(), t, self.p_list))

    def applied(self, q: Array, qd: Array | None, t: float) -> Array:
        return np.array(self.module._applied_s(q.tolist(), None if qd is None else qd.tolist(), t, self.p_list))

    def mass(self) -> Array:
        return np.array(self.module._mass_s(self.p_list))

    def reactions(self, q: Array, lam: Array, t: float) -> Array:
        return np.array(self.module._reactions_s(q.tolist(), lam.tolist(), t, self.p_list))


class NumpyBackend:
    """Registry entry: the generated NumPy module."""

    name = "numpy"

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs) -> NumpyEvaluator:
        from symid.codegen.model import options_for

        path = build(layout, options_for(layout.mechanism))
        return NumpyEvaluator(path, {s.name: v for s, v in values.items()}, layout)

    def load(self, artifact: Path, name: str, params: Mapping[str, float]) -> NumpyEvaluator:
        """The module generated earlier at `artifact` (a cached run, `symid.plan`)."""
        if not (artifact.parent / "complete").is_file():
            raise FileNotFoundError(f"{artifact}: not a complete build")
        return NumpyEvaluator(artifact, params, None)
