"""The constraint library: one module per family, one registry.

Each module only writes `Phi` on the generic symbols of `symid.symbolic.symbols`;
`symid.symbolic.derive` derives everything else.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from symid.symbolic.constraints import angle, distance, expression, gear, parallel, rack, revolute, slot
from symid.model.elements import ConstraintType

if TYPE_CHECKING:
    from symid.model.mechanism import Element

TYPES: dict[str, ConstraintType] = {
    c.name: c
    for module in (revolute, distance, parallel, slot, angle, gear, rack, expression)
    for c in module.TYPES
}


def family_of(element: "Element") -> ConstraintType:
    """The family of a constraint element as its variant has it: its rows and
    driver flag (an expression constraint's depend on its rows)."""
    return TYPES[element.type].at(element.options)
