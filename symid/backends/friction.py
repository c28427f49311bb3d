"""Joint friction on the backends: which solve it, and the friction model an
evaluator carries (`symid.numeric.friction`), read by the shared Python loop."""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping

from symid.errors import InputError
from symid.model.friction import has_friction

if TYPE_CHECKING:
    import sympy as sp

    from symid.backends import Evaluator
    from symid.model.mechanism import Mechanism
    from symid.symbolic.assemble import Layout


def first_joint(mech: Mechanism) -> str | None:
    """The first constraint with friction, None if none has."""
    return next((c.name for c in mech.constraints if has_friction(c)), None)


def solved(mech: Mechanism) -> bool:
    """Whether the mechanism's analysis involves friction (inverse dynamics of
    a mechanism with friction; statics and kinematics have none)."""
    return mech.analysis.kind == "inverse_dynamics" and first_joint(mech) is not None


def require(backend_name: str, backend: object, mech: Mechanism) -> None:
    """An input error, before any build, when the backend cannot solve friction."""
    if solved(mech) and not getattr(backend, "solves_friction", True):
        from symid.backends import names, get

        able = [n for n in names() if getattr(get(n), "solves_friction", True)]
        raise InputError(f"{mech.source}: constraint '{first_joint(mech)}' key 'friction': the {backend_name} "
                         f"backend does not solve joint friction yet; use --backend {' or '.join(able)}")


def attach(evaluator: Evaluator, layout: Layout, values: Mapping[sp.Symbol, float]) -> Evaluator:
    """Give the evaluator its mechanism's friction model (when the analysis has friction)."""
    if solved(layout.mechanism):
        from symid.numeric.friction import FrictionModel

        evaluator.friction = FrictionModel(layout, values)  # type: ignore[attr-defined]
    return evaluator


def rebind(evaluator: object, params: Mapping[str, float]) -> None:
    """Give a copy made by `with_params` (name -> value) a friction model of
    its own parameter values: mu, radius, viscous... follow the variant, not
    the evaluator it was copied from."""
    model = getattr(evaluator, "friction", None)
    if model is not None:
        evaluator.friction = model.with_params(params)  # type: ignore[attr-defined]
