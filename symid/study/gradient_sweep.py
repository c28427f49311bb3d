"""`symid sweep --gradients`: each variant's figures and their exact gradients
with respect to the varied parameters.

The batch engines (compiled C, NumPy over variants) compute no sensitivities,
so each variant is solved on its own (its backend's solver with sensitivities:
compiled on c, the Python loop on numpy) with the exact sensitivities of the
columns the figures are read from (`symid.study.gradients`): slower than a
plain sweep, and exact. The columns follow the figures: `d(FIGURE)/d(P)` for
every figure (outer, in figure order) and every varied parameter (inner, in
the order given).
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from symid.model.mechanism import Mechanism
from symid.output.results import columns
from symid.study.design import Variants
from symid.study.figures import STATUS, Figures, cond_of, figure_names, status_of
from symid.study.gradients import figure_gradients, gradient_names, needed_columns
from symid.study.optimize import Solver
from symid.study.run import Sweep
from symid.study.slow import figures_of, study_analysis, with_values
from symid.symbolic.assemble import assemble


class GradientSweep(Sweep):
    """A sweep whose table adds `d(FIGURE)/d(P)` after the figures (see the module).

    Args:
        mechanism, variants, backend: as `Sweep`; solver: solves one variant
            with the sensitivities asked for (`symid.tools.sensitive.solver`).
    """

    def __init__(self, mechanism: Mechanism, variants: Variants, backend: str, solver: Solver) -> None:
        super().__init__(mechanism, variants, backend)
        self.solver = solver
        self.study = study_analysis(mechanism)
        self.needed = needed_columns(self.study, columns(assemble(self.study), self.study.analysis))

    def columns(self) -> tuple[str, ...]:
        return figure_names(self.mechanism) + tuple(gradient_names(figure_names(self.mechanism),
                                                                   self.variants.names))

    def setup(self) -> None:
        """Nothing to build ahead: each variant builds or loads its solver from the cache."""

    def _local(self) -> Iterator[int]:
        names = self.variants.names
        width = len(self.columns())
        for row, values in enumerate(self.variants.values):
            variant = with_values(self.study, names, values)
            out = np.full((1, width), np.nan)
            status, t_end, cond = 0, np.nan, 0.0
            try:
                results = self.solver(variant, names, self.needed)
            except ValueError:  # a derived parameter is not finite for these values: nothing solved
                status = STATUS.index("nonfinite")
            else:
                figures = figures_of(variant, results)
                out[0] = np.concatenate([figures, figure_gradients(variant, results, names).ravel()])
                t_end = results.t[-1] if len(results.t) else np.nan
                status = status_of(results.error)
                cond = cond_of(results.warnings)
            self.parts[row] = Figures(self.columns(), out, np.array([status], dtype=np.int8), np.array([t_end]),
                                      np.array([cond]))
            yield 1
