"""The constraint library: one module per family, one registry.

Each module only writes `Phi` on the generic symbols of `symid.symbolic.symbols`;
`symid.symbolic.derive` derives everything else.
"""

from __future__ import annotations

from symid.symbolic.constraints import angle, distance, gear, parallel, rack, revolute, slot
from symid.model.elements import ConstraintType

TYPES: dict[str, ConstraintType] = {
    c.name: c
    for module in (revolute, distance, parallel, slot, angle, gear, rack)
    for c in module.TYPES
}
