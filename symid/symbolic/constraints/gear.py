"""Gear pairs (also chain and belt drives), on the ground or on a rotating carrier.

The rows relate angles only: their reactions are pure couples. The tooth
force at the pitch point is not represented, so bearing loads from gear
teeth are not in the reactions.
"""

from __future__ import annotations

from typing import Any

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, Key, body, scalar

_RATIO_KEYS = (
    scalar("K", default=None),
    scalar("radius_i", default=None),
    scalar("radius_j", default=None),
    Key("internal", "flag", default=False),
    scalar("C", default=0),
)


def _ratio(values: dict[str, Any], where: str) -> dict[str, Any]:
    """Replace radii (and `internal`) by K = -+ radius_i / radius_j."""
    has_k = values.get("K") is not None
    radii = [values.get("radius_i"), values.get("radius_j")]
    if has_k and any(r is not None for r in radii):
        raise ValueError(f"{where}: give either 'K' or 'radius_i' and 'radius_j', not both")
    if not has_k:
        if any(r is None for r in radii):
            missing = "radius_i" if radii[0] is None else "radius_j"
            raise ValueError(f"{where}: missing key '{missing}' (or give 'K')")
        if radii[1] == 0:
            raise ValueError(f"{where} key 'radius_j': must not be zero")
        sign = 1 if values["internal"] else -1
        values["K"] = sign * radii[0] / radii[1]  # type: ignore[operator]
    for key in ("radius_i", "radius_j", "internal"):
        values.pop(key, None)
    return values


def _k() -> Any:
    return s.scalar("K")


gear = ConstraintType(
    name="gear",
    keys=(body("i"), body("j")) + _RATIO_KEYS,
    points={"i": None, "j": None},
    resolve=_ratio,
    phi=lambda o: [s.q("j")[2] - _k() * s.q("i")[2] - s.scalar("C")],
)

gear_on_link = ConstraintType(
    name="gear_on_link",
    keys=(body("i"), body("j"), body("k")) + _RATIO_KEYS,
    points={"i": None, "j": None, "k": None},
    resolve=_ratio,
    phi=lambda o: [
        (s.q("j")[2] - s.q("k")[2]) - _k() * (s.q("i")[2] - s.q("k")[2]) - s.scalar("C")
    ],
)

TYPES = (gear, gear_on_link)
