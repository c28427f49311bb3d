"""The reference backend: the reference evaluator (`symid.numeric.reference`)
behind the backend protocol."""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping

import sympy as sp

from symid.numeric.evaluator import Capabilities, Needs
from symid.numeric.reference import ReferenceEvaluator
from symid.symbolic.assemble import Layout

if TYPE_CHECKING:
    from symid.numeric.friction import FrictionModel

__all__ = ["ReferenceBackend", "ReferenceEvaluator"]


class ReferenceBackend:
    """Registry entry for `ReferenceEvaluator`."""

    name = "reference"
    capabilities: Capabilities = ReferenceEvaluator.capabilities

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                  friction: FrictionModel | None = None) -> ReferenceEvaluator:
        return ReferenceEvaluator(layout, values, needs, friction)
