"""Read a joint's `friction = {...}` inline table (contract v1.1).

Every problem is one `InputError` naming the file, the element and the key.
"""

from __future__ import annotations

from typing import Any, Callable

import sympy as sp

from symid.errors import InputError
from symid.model.friction import DEFAULTS, FAMILIES, KEYS
from symid.text import number

Number = Callable[[Any, str], tuple[sp.Expr, float]]


def read(raw: Any, family: str, where: str, source: str, value_of: Number) -> dict[str, sp.Expr]:
    """The friction table of the element at `where` (its `friction` key given).

    Args:
        raw: the TOML value of the key.
        family: the element's type.
        value_of: the reader's number parser: (raw, where) -> (expression, value).

    Returns:
        key -> expression, defaults filled in; `arm` only when given.
    """
    here = f"{where} key 'friction'"
    if family not in FAMILIES:
        raise InputError(f"{source}: {here}: a {family} has no friction (friction is for "
                         f"{', '.join(FAMILIES)})")
    if not isinstance(raw, dict):
        raise InputError(f"{source}: {here}: must be an inline table "
                         f"{{ mu = ..., radius = ..., viscous = ..., arm = ..., v_smooth = ... }}")
    for key in raw:
        if key not in KEYS:
            raise InputError(f"{source}: {where} key 'friction.{key}': unknown friction key (allowed: {', '.join(KEYS)})")
    if "mu" not in raw and "viscous" not in raw:
        raise InputError(f"{source}: {here}: needs 'mu' (Coulomb) or 'viscous' (or both)")
    out: dict[str, sp.Expr] = {}
    values: dict[str, float] = {}
    for key in KEYS:
        if key not in raw:
            continue
        at = f"{where} key 'friction.{key}'"
        expr, value = value_of(raw[key], at)
        if value < 0:
            raise InputError(f"{source}: {at}: must not be negative (it is {number(value)})")
        if key == "arm" and value == 0:
            raise InputError(f"{source}: {at}: must be positive (N adds |T| / arm)")
        out[key], values[key] = expr, value
    if family == "revolute" and "mu" in raw and "radius" not in raw:
        raise InputError(f"{source}: {where} key 'friction.radius': missing: a revolute with mu needs the pin radius")
    for key, default in DEFAULTS.items():
        out.setdefault(key, sp.Float(default) if key == "v_smooth" else sp.Integer(0))
    return out
