"""A variant solved with the exact sensitivities of chosen columns: the
`Solver` of `symid.study.optimize` and of `symid sweep --gradients`.

The sensitivities are the API's (`api.prepare(..., sensitivity=...,
sensitivity_of=...)`): implicit differentiation of the solved instants, never
finite differences.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Sequence

from symid import api
from symid.api import Study
from symid.model.mechanism import Mechanism
from symid.model.params import parameter_values, without_values
from symid.output.results import Results


def solver(backend: str) -> Callable[[Mechanism, Sequence[str], Sequence[str]], Results]:
    """A function solving a variant on `backend`, with `d(C)/d(P)` for the
    columns C and base parameters P it is given (none: the plain run).

    The study prepared for one variant serves the next ones that differ from
    it in base parameter values only: its solver takes their values
    (`Capabilities.with_params`), so the layout, the cache key of the generated
    solver (which prints every expression) and its loading are done once per
    run, not once per point (0.05 s a point on the c backend).
    """
    last: list[tuple[object, Study]] = []  # (what it was prepared for, the study): the latest only

    def solve(mechanism: Mechanism, names: Sequence[str], columns: Sequence[str]) -> Results:
        shape = (without_values(mechanism), tuple(names), tuple(columns))
        if last and last[0][0] == shape:
            return _again(last[0][1], mechanism).solve()
        if not names:
            study = api.prepare(mechanism, backend=backend)
        else:
            study = api.prepare(mechanism, backend=backend, sensitivity=list(names), sensitivity_of=list(columns))
        if study.solver is not None and study.solver.capabilities.with_params:  # the reference: built per variant
            last[:] = [(shape, study)]
        return study.solve()

    return solve


def _again(study: Study, mechanism: Mechanism) -> Study:
    """`study` for `mechanism`, which differs from its own in base parameter
    values only: the same solver with the variant's values, and a layout that
    names the variant (a failure's diagnosis reads its parameters)."""
    assert study.solver is not None  # prepared by `solver` above
    solver = study.solver.with_values(parameter_values(mechanism.parameters), mechanism)
    return dataclasses.replace(study, mechanism=mechanism, layout=solver.layout, evaluator=solver.evaluator,
                               values=solver.values, notes=None, results=None, solver=solver)
