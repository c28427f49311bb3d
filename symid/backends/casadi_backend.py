"""The CasADi backend: the mechanism's saved `casadi.Function`s (cached by model
hash), driven by the shared Python loop with numpy in and out."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import casadi as ca
import numpy as np
import sympy as sp

from symid.symbolic.assemble import Layout
from symid.backends import Array, Capabilities, Needs
from symid.codegen.cache import cached
from symid.codegen.flat import Options
from symid.model.mechanism import parameter_symbol

if TYPE_CHECKING:
    from symid.numeric.friction import FrictionModel


def build(layout: Layout, options: Options) -> Path:
    """The cache folder holding the saved functions, writing them if needed.

    Only the flat system is built: the elimination plan of `code_model` is
    for the C target and would cost a Newton solve here for nothing.
    """
    mech = layout.mechanism

    def make(folder: Path) -> None:
        from symid.codegen import flat
        from symid.codegen.targets import casadi_target
        from symid.model.mechanism import parameter_symbol
        from symid.model.params import base_names, parameter_values

        values = parameter_values(mech.parameters)
        defaults = [values[parameter_symbol(n)] for n in base_names(mech.parameters)]
        # the Python loop drives the backend: no `instant`, which costs most of the build
        casadi_target.write(flat.build(layout, options, defaults), folder, instant=False)

    return cached(mech, options, "casadi", make, ("manifest.json",))


class CasadiEvaluator:
    """The saved functions of one mechanism, with numeric parameter values.

    Sizes as `symid.backends.Evaluator`; every call converts numpy in and out
    (phi_q comes back dense). Quantities the options leave out (nu, gamma without velocity; applied,
    mass without multipliers; reactions when none are asked) are not built.
    """

    # driven by the shared Python loop; one set of loaded functions serves many variants
    capabilities = Capabilities(with_params=True, setup_kb=110.0)

    def __init__(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                 options: Options, friction: FrictionModel | None = None) -> None:
        self.layout = layout
        self.needs = needs
        self.friction = friction
        folder = build(layout, options)
        self.manifest = json.loads((folder / "manifest.json").read_text())
        self._fn = {key: ca.Function.load(str(folder / f["file"]))
                    for key, f in self.manifest["functions"].items()}
        # p in the order the functions take it (the manifest's, i.e. the file's)
        self.p = np.array([values[parameter_symbol(par["name"])] for par in self.manifest["parameters"]],
                          dtype=float)
        sizes = self.manifest["sizes"]
        self.ng, self.nc = sizes["ng"], sizes["nc"]

    def with_params(self, params: Mapping[str, float]) -> "CasadiEvaluator":
        """The same functions with other parameter values (name -> value; the
        base ones are read): one set of loaded functions, many variants."""
        other = copy.copy(self)
        other.p = np.array([params[par["name"]] for par in self.manifest["parameters"]], dtype=float)
        other.friction = self.friction.with_params(params) if self.friction is not None else None
        return other

    def _call(self, key: str, *args: Array | float) -> Array:
        fn = self._fn.get(key)
        if fn is None:
            raise RuntimeError(f"casadi backend: {key} was not generated for this analysis "
                               f"(kind and outputs leave it out)")
        return np.asarray(fn(*args, self.p).full()).ravel()

    def phi(self, q: Array, t: float) -> Array:
        return self._call("phi", q, t)

    def phi_q(self, q: Array, t: float) -> Array:
        return np.asarray(self._fn["phi_q"](q, t, self.p).full())

    def phi_q_sparse(self, q: Array, t: float):  # type: ignore[no-untyped-def]
        from scipy import sparse

        jac = self._fn["phi_q"](q, t, self.p)  # a CasADi DM: its own sparsity, nothing nc x ng
        rows, cols = jac.sparsity().get_triplet()
        return sparse.csc_matrix((np.array(jac.nonzeros(), dtype=float), (rows, cols)), shape=(self.nc, self.ng))

    def nu(self, q: Array, t: float) -> Array:
        return self._call("nu", q, t)

    def gamma(self, q: Array, qd: Array, t: float) -> Array:
        return self._call("gamma", q, qd, t)

    def applied(self, q: Array, qd: Array | None, t: float) -> Array:
        # without velocity terms the function ignores qd; it still takes one
        return self._call("applied", q, qd if qd is not None and self.needs.velocity else np.zeros(self.ng), t)

    def mass(self) -> Array:
        if "mass" not in self._fn:
            # the loop asks for M once up front even when no multiplier is
            # solved; NaN makes any other use visible
            return np.full(self.ng, np.nan)
        return self._call("mass")

    def reactions(self, q: Array, lam: Array, t: float) -> Array:
        return self._call("reactions", q, lam, t)


class CasadiBackend:
    """Registry entry: the saved CasADi functions."""

    name = "casadi"
    capabilities = CasadiEvaluator.capabilities

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                  friction: FrictionModel | None = None) -> CasadiEvaluator:
        from symid.codegen.model import options_for

        return CasadiEvaluator(layout, values, needs, options_for(layout.mechanism), friction)
