"""A provisional provider of the sensitivity columns `d(COLUMN)/d(NAME)`, by
central differences of whole solves, for tests only.

It stands in for the exact sensitivities (`api.prepare(..., sensitivity=...)`)
where a test needs the columns without depending on how they are computed:
its values are finite differences, never presented as exact.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from symid.model.mechanism import Mechanism, parameter_symbol
from symid.model.params import parameter_values
from symid.output.results import Results
from symid.study.gradients import sensitivity_column
from symid.study.slow import solve_variant, with_values

RELATIVE_STEP = 1e-6  # central differences: truncation ~h^2, rounding ~eps/h: ~1e-10 of a column's scale


def solve(mechanism: Mechanism, names: Sequence[str], columns: Sequence[str], backend: str = "numpy") -> Results:
    """`mechanism` solved on `backend`, with `d(C)/d(P)` for C in `columns`
    (outer) and P in `names` (inner) appended by central differences."""
    base = solve_variant(mechanism, backend)
    values = parameter_values(mechanism.parameters)
    extra: dict[tuple[str, str], np.ndarray] = {}
    for name in names:
        p = values[parameter_symbol(name)]
        h = RELATIVE_STEP * max(abs(p), 1e-3)
        up = solve_variant(with_values(mechanism, [name], [p + h]), backend)
        down = solve_variant(with_values(mechanism, [name], [p - h]), backend)
        k = min(len(up.t), len(down.t), len(base.t))
        for column in columns:
            d = np.full(len(base.t), np.nan)
            d[:k] = (up[column][:k] - down[column][:k]) / (2 * h)
            extra[(column, name)] = d
    header = list(base.columns) + [sensitivity_column(c, n) for c in columns for n in names]
    data = np.column_stack([base.data] + [extra[(c, n)] for c in columns for n in names])
    return Results(header, data.reshape(len(base.t), len(header)), base.error, mechanism=mechanism)


def solver(backend: str):
    """Stands in for `symid.tools.sensitive.solver` (same signature) with finite differences."""

    def solve_one(mechanism: Mechanism, names: Sequence[str], columns: Sequence[str]) -> Results:
        return solve(mechanism, names, columns, backend) if names else solve_variant(mechanism, backend)

    return solve_one


def exact_available() -> bool:
    """Whether the API computes the exact sensitivities (`api.prepare(..., sensitivity=...)`)."""
    import inspect

    from symid import api

    return "sensitivity" in inspect.signature(api.prepare).parameters
