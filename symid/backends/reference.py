"""The reference backend: the reference evaluator (`symid.numeric.reference`)
behind the backend protocol."""

from __future__ import annotations

from typing import Mapping

import sympy as sp

from symid.numeric.evaluator import Needs
from symid.numeric.reference import ReferenceEvaluator
from symid.symbolic.assemble import Layout

__all__ = ["ReferenceBackend", "ReferenceEvaluator"]


class ReferenceBackend:
    """Registry entry for `ReferenceEvaluator`."""

    name = "reference"

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs) -> ReferenceEvaluator:
        return ReferenceEvaluator(layout, values, needs)
