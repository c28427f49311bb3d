"""Joint friction on the backends: which analyses solve it and which backends
can. The friction model itself (`symid.numeric.friction`) is built with the
solver (`symid.backends.prepare`) and given to its evaluator."""

from __future__ import annotations

from typing import TYPE_CHECKING

from symid.errors import InputError
from symid.model.friction import has_friction

if TYPE_CHECKING:
    from symid.model.mechanism import Mechanism


def first_joint(mech: Mechanism) -> str | None:
    """The first constraint with friction, None if none has."""
    return next((c.name for c in mech.constraints if has_friction(c)), None)


def solved(mech: Mechanism) -> bool:
    """Whether the mechanism's analysis involves friction (inverse dynamics of
    a mechanism with friction; statics and kinematics have none)."""
    return mech.analysis.kind == "inverse_dynamics" and first_joint(mech) is not None


def require(backend_name: str, mech: Mechanism) -> None:
    """An input error, before any build, when the backend cannot solve friction."""
    from symid.backends import capabilities, names

    if solved(mech) and not capabilities(backend_name).solves_friction:
        able = [n for n in names() if capabilities(n).solves_friction]
        raise InputError(f"{mech.source}: constraint '{first_joint(mech)}' key 'friction': the {backend_name} "
                         f"backend does not solve joint friction yet; use --backend {' or '.join(able)}")
