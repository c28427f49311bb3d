"""The one place a solver is built: the mechanism laid out, its parameter
values, the checks of what the backend can do, the backend's evaluator and
the friction model, in that order.

The API (`symid.api.prepare`), the command line through it, the studies
(`symid.study`), the sensitivities (`symid.tools.sensitive`) and the
benchmarks (`symid.tools.bench`) all get their solvers here. What a backend
can do is read from its declared `Capabilities`, never probed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

import numpy as np

from symid import backends
from symid.backends import friction
from symid.errors import InputError
from symid.model.params import initial_guess
from symid.numeric.evaluator import Array, Capabilities, Evaluator, Needs

if TYPE_CHECKING:
    import sympy as sp

    from symid.backends import Backend
    from symid.model.mechanism import Mechanism
    from symid.numeric.friction import FrictionModel
    from symid.symbolic.assemble import Layout


def needs_of(mechanism: Mechanism) -> Needs:
    """What a run of the mechanism's `[analysis]` asks of an evaluator: the
    velocity terms (not for statics) and the reactions it solves."""
    return Needs(velocity=mechanism.analysis.kind != "statics", reactions=mechanism.solved_reactions)


@dataclass(frozen=True)
class Solver:
    """A mechanism built for one backend: what a run of it needs.

    Attributes:
        mechanism: the description; layout: its rows and columns.
        backend: the backend's name; capabilities: what it declares it can do.
        evaluator: the backend's numeric workspace, carrying `friction`.
        values: every parameter's value; needs: what the evaluator computes.
    """

    mechanism: Mechanism
    layout: Layout
    backend: str
    capabilities: Capabilities
    evaluator: Evaluator
    values: Mapping[sp.Symbol, float]
    needs: Needs

    @property
    def friction(self) -> FrictionModel | None:
        """The joint friction model the Python loop solves with (None: no friction)."""
        return self.evaluator.friction

    def q0(self) -> Array:
        """The initial guess at these values, size ng (a copy: the caller may change it)."""
        if self.values is self.layout.values:  # computed once, with the layout
            return np.array(self.layout.q0)
        return initial_guess(self.mechanism, self.values)

    def with_values(self, values: Mapping[sp.Symbol, float], mechanism: Mechanism | None = None) -> Solver:
        """The same solver with other parameter values (every parameter, derived
        ones included): the built solver takes them (`Capabilities.with_params`),
        or one is built for them (the reference backend), friction model included.

        Args:
            mechanism: the variant's own description, differing from this one
                in parameter values only; it then names the evaluator's failures.
        """
        mech = mechanism if mechanism is not None else self.mechanism
        layout = self.layout if mechanism is None else dataclasses.replace(self.layout, mechanism=mech)
        if self.capabilities.with_params:
            evaluator = self.evaluator.with_params({s.name: v for s, v in values.items()})  # type: ignore[attr-defined]
            if mechanism is not None:
                evaluator.layout = layout  # a copy of its own
        else:
            evaluator = _evaluator(backends.get(self.backend), layout, values, self.needs)
        return dataclasses.replace(self, mechanism=mech, layout=layout, evaluator=evaluator, values=values)


def check(mechanism: Mechanism, backend: str, layout: Layout | None = None) -> Backend:
    """The backend, after the checks of what it can do for this mechanism at its
    own values (`prepare` runs them; a study runs them once before choosing
    its engine).

    Raises:
        InputError: an unknown backend, a feature of `[analysis]` it lacks, a
            run whose memory estimate is above the limit (`footprint`), more
            rows than coordinates (naming the dependent rows), or friction it
            does not solve; each the one line the command line gives.
    """
    from symid.backends import footprint
    from symid.symbolic.assemble import assemble

    layout = layout if layout is not None else assemble(mechanism)
    backends.require_support(backend, mechanism.analysis, mechanism.source)
    footprint.require_within(layout, backend)  # before the rank analysis: it may be the dense part
    backends.check_redundant(layout, layout.values, backend)
    chosen = backends.get(backend)
    friction.require(backend, mechanism)
    return chosen


def prepare(mechanism: Mechanism, backend: str, needs: Needs | None = None, layout: Layout | None = None,
            values: Mapping[sp.Symbol, float] | None = None) -> Solver:
    """Build (or load from the cache) the solver of `mechanism` on `backend`.

    Args:
        needs: what the caller wants computed (default: what the `[analysis]`
            asks, `needs_of`); sensitivities (`Needs.sensitivity`) are computed
            in the backend's own loop when it declares them, else by the
            Python loop; `Needs.batch`: the batch entry will run.
        layout: the mechanism's layout, when the caller has it already.
        values: every parameter's value to build at (a study's first variant;
            default the mechanism's own, at which the checks run either way).

    Raises:
        InputError: what `check` refuses, or a batch entry the backend lacks.
    """
    from symid.symbolic.assemble import assemble

    layout = layout if layout is not None else assemble(mechanism)
    needs = needs if needs is not None else needs_of(mechanism)
    chosen = check(mechanism, backend, layout)
    if needs.batch and chosen.capabilities.batch is None:
        able = [n for n in backends.names() if backends.capabilities(n).batch is not None]
        raise InputError(f"--backend {backend}: the {backend} backend has no batch entry; use --backend "
                         f"{' or '.join(able)}")
    values = values if values is not None else layout.values
    evaluator = _evaluator(chosen, layout, values, needs)
    return Solver(mechanism, layout, backend, chosen.capabilities, evaluator, values, needs)


def _evaluator(chosen: Backend, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs) -> Evaluator:
    """The backend's evaluator at `values`, given the friction model of those
    values when the analysis solves friction in a Python loop."""
    model = None
    if friction.solved(layout.mechanism) and needs.friction:
        from symid.numeric.friction import FrictionModel

        model = FrictionModel(layout, values)
    return chosen.evaluator(layout, values, needs, model)


__all__ = ["Solver", "check", "needs_of", "prepare"]
