"""A variant solved with the exact sensitivities of chosen columns: the
`Solver` of `symid.study.optimize` and of `symid sweep --gradients`.

The sensitivities are the API's (`api.prepare(..., sensitivity=...,
sensitivity_of=...)`): implicit differentiation of the solved instants, never
finite differences.
"""

from __future__ import annotations

from typing import Callable, Sequence

from symid import api
from symid.model.mechanism import Mechanism
from symid.output.results import Results


def solver(backend: str) -> Callable[[Mechanism, Sequence[str], Sequence[str]], Results]:
    """A function solving a variant on `backend`, with `d(C)/d(P)` for the
    columns C and base parameters P it is given (none: the plain run)."""

    def solve(mechanism: Mechanism, names: Sequence[str], columns: Sequence[str]) -> Results:
        if not names:
            return api.prepare(mechanism, backend=backend).solve()
        study = api.prepare(mechanism, backend=backend, sensitivity=list(names), sensitivity_of=list(columns))
        return study.solve()

    return solve
