"""The protocol every backend's evaluator implements, and what an analysis needs of it.

The solve loop and the stability tools know backends only through this; the
registry that builds evaluators is `symid.backends`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TYPE_CHECKING, Literal, Protocol

import numpy as np

if TYPE_CHECKING:  # a cached run (symid.tools.plan) loads a backend without sympy
    from symid.numeric.friction import FrictionModel
    from symid.symbolic.assemble import Layout

Array = np.ndarray


@dataclass(frozen=True)
class Needs:
    """What an analysis will ask of an evaluator, so nothing else is prepared.

    Attributes:
        velocity: False for statics: applied forces see qdot = 0 and no
            velocity or acceleration term is compiled.
        reactions: names of constraints whose reactions are wanted (file order).
        sensitivity, sensitivity_of: the run's d(COLUMN)/d(NAME) columns
            (parameters, columns), for an evaluator whose own loop computes
            them (the c backend's); the others leave them to the Python loop.
        batch: the caller runs the backend's batch entry (a study's
            variants): refused by a backend without one.
        friction: the friction model of the Python loop, when the analysis
            has friction (False: no Python loop will run, e.g. only the
            batch entry, or the build only fills the cache).
    """

    velocity: bool = True
    reactions: tuple[str, ...] = ()
    sensitivity: tuple[str, ...] = ()
    sensitivity_of: tuple[str, ...] = ()
    batch: bool = False
    friction: bool = True


@dataclass(frozen=True)
class Capabilities:
    """What a backend's solvers can do, declared once on the backend (and on
    its evaluators) and read, never probed. The defaults are the shared
    Python loop's: everything an analysis may ask, nothing of its own.

    Attributes:
        own_loop: the evaluator runs whole tables itself (`rows(analysis, q0,
            notes)`), handing the Python loop the instants it cannot vouch for.
        blocks: its rows also come as 2-D blocks (`blocks(analysis, q0, notes)`).
        compiled_loop: that loop is compiled code called a chunk at a time
            (`symid bench` times it without Python per instant).
        batch: how a study runs many variants: "compiled" (the solver's batch
            entry, on threads), "vectorized" (all variants of a chunk at once),
            None (variant by variant through the normal path).
        batch_friction: the batch path solves joint friction too.
        with_params: one built solver takes other parameter values at run time
            (`with_params(params)`); otherwise one is built per variant.
        sensitivities: its own loop computes the d(COLUMN)/d(NAME) columns of
            `Needs.sensitivity` (`sensitivity_header`, `sensitivity_row`).
        solves_friction: it solves joint friction (inverse dynamics).
        loads: a solver it built can be loaded again without sympy
            (`load(artifact, name, params)`, `artifact`: a planned run).
        lacks: the `[analysis]` features it cannot provide
            (`symid.numeric.stability.FEATURES` keys).
        setup_kb: the memory its setup holds per coordinate, kB (measured:
            `symid.backends.footprint`); the default is what the generated
            Python module took when compiled in one piece (the reference
            backend keeps it).
    """

    own_loop: bool = False
    blocks: bool = False
    compiled_loop: bool = False
    batch: Literal["compiled", "vectorized"] | None = None
    batch_friction: bool = False
    with_params: bool = False
    sensitivities: bool = False
    solves_friction: bool = True
    loads: bool = False
    lacks: frozenset[str] = frozenset()
    setup_kb: float = 220.0


class Evaluator(Protocol):
    """Numeric values of one mechanism's derived quantities at one instant.

    Sizes: q, qd: (ng,); results of phi, nu, gamma: (nc,); phi_q: (nc, ng);
    applied: (ng,); mass: (ng,) (the diagonal of M); reactions: (3 * roles,)
    per requested constraint, concatenated in file order. `friction`: the
    joint friction model the Python loop solves with (given when the
    evaluator is built, `symid.backends.prepare`), None without friction.
    """

    layout: Layout
    capabilities: Capabilities
    friction: FrictionModel | None

    def phi(self, q: Array, t: float) -> Array: ...
    def phi_q(self, q: Array, t: float) -> Array: ...
    def phi_q_sparse(self, q: Array, t: float) -> Any:
        """Phi_q as a scipy CSC matrix (nc, ng), nothing nc x ng: the Python
        loop's from `symid.numeric.stability.SPARSE_MIN` coordinates on."""
        ...
    def nu(self, q: Array, t: float) -> Array: ...
    def gamma(self, q: Array, qd: Array, t: float) -> Array: ...
    def applied(self, q: Array, qd: Array | None, t: float) -> Array: ...
    def mass(self) -> Array: ...
    def reactions(self, q: Array, lam: Array, t: float) -> Array: ...
