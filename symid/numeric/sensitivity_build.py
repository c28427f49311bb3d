"""What the sensitivities of one mechanism *structure* need, built once and
cached in the process: parameter values are inputs, never baked in.

Two kinds of lambdified code, each a handful of calls per run or instant:

- `FusedKernel` (per family variant and set of Jacobians): every Jacobian of
  a group that one instant needs, in one call over the group's members. The
  entries that are numbers (most of them: zeros, ones) are a constant
  template; only the others are computed.
- `Structure` (per mechanism structure and chosen parameters): the members'
  constants, masses and the chain d(constants, masses, weights)/d(p) in one
  function of the parameter values (once per run), and every member's time
  functions and their chain in one function of (t, parameter values) (once
  per instant). A new value of a base parameter reuses all of it: no sympy
  derivation and no lambdify (the point of issue #15's "one solver serves
  every value").

`BUILDS` counts the lambdify calls made here (read by tests: a second
parameter value must not build again).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.model.mechanism import T, Mechanism, parameter_symbol
from symid.numeric.evaluator import Array
from symid.symbolic.assemble import Group, Layout
from symid.symbolic.sensitivity import (ConstraintSensitivity, ForceSensitivity, parameter_chain,
                                        sensitivity_of)

BUILDS = {"lambdify": 0}
_KERNELS: dict[tuple, "FusedKernel"] = {}
_STRUCTURES: dict[tuple, "Structure"] = {}


def _lambdify(args: Sequence[sp.Symbol], exprs: Sequence[sp.Expr]) -> Callable[..., list]:
    BUILDS["lambdify"] += 1
    return sp.lambdify(list(args), list(exprs), modules=[np], cse=True)


@dataclass(frozen=True, eq=False)
class FusedKernel:
    """The Jacobians `whats` of one family variant, stacked row-wise.

    Attributes:
        rows: what -> slice of its rows in the stacked matrix.
        nargs: the number of local arguments (columns).
        template: (entries,) the number entries (others 0); live: the indices of the others.
    """

    rows: Mapping[str, slice]
    nargs: int
    template: Array
    live: Array
    fn: Callable[..., list] | None

    def __call__(self, args: list, n: int) -> Array:
        """(stacked rows, nargs, members) at the members' arguments (each (n,))."""
        out = np.repeat(self.template[:, None], n, axis=1)
        if self.fn is not None:
            vals = self.fn(*args)
            try:
                out[self.live] = vals
            except ValueError:  # an entry came out a scalar (it cancelled in the members' arguments)
                out[self.live] = [np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in vals]
        return out.reshape(-1, self.nargs, n)


def fused(sens: ConstraintSensitivity | ForceSensitivity, whats: tuple[str, ...]) -> FusedKernel:
    """The fused kernel of `whats` for a family variant (cached)."""
    key = (sens, whats)  # by identity (eq=False), and kept alive here: never another's kernel
    if key in _KERNELS:
        return _KERNELS[key]
    matrices = [getattr(sens, w) for w in whats]
    rows, at = {}, 0
    for w, m in zip(whats, matrices):
        rows[w] = slice(at, at + m.rows)
        at += m.rows
    entries = [e for m in matrices for e in m]  # row-major: (row, arg)
    template = np.array([float(e) if e.is_number else 0.0 for e in entries])
    live = np.array([k for k, e in enumerate(entries) if not e.is_number], dtype=np.intp)
    fn = _lambdify(sens.args, [entries[k] for k in live]) if live.size else None
    kernel = FusedKernel(rows, len(sens.args), template, live, fn)
    _KERNELS[key] = kernel
    return kernel


@dataclass(frozen=True, eq=False)
class Structure:
    """Lambdified chain of one mechanism structure for base parameters `names`.

    Attributes:
        symbols: the parameter symbols the functions take, in order.
        static: values -> flat [per group: constants, d(constants)/dp; masses; d(mass)/dp; d(weight)/dp].
        timed: (t, values) -> flat [per group: functions, d(functions)/dp], or None.
        shapes: per constraint then force group, (n, nconst, nfun series width).
    """

    symbols: tuple[sp.Symbol, ...]
    static: Callable[..., list]
    timed: Callable[..., list] | None
    shapes: tuple[tuple[int, int, int], ...]


def _series(group: Group) -> list[list[sp.Expr]]:
    """Per member, the time functions a group's kernels take (constraints: f, f', f'')."""
    out = []
    for member in group.functions:
        if group.kind == "constraint" and member:
            out.append([sp.diff(member[0], T, order) for order in range(3)])
        else:
            out.append(list(member))
    return out


def _key(mechanism: Mechanism, layout: Layout, names: tuple[str, ...]) -> tuple:
    """Everything the structure depends on but base parameters' values."""
    params = mechanism.parameters
    derived = tuple((n, sp.sympify(e)) for n, e in params.items() if sp.sympify(e).free_symbols)
    groups = tuple((g.kind, g.family, g.variant, tuple(map(tuple, g.constants)), tuple(map(tuple, g.functions)))
                   for g in (*layout.constraint_groups, *layout.force_groups))
    bodies = tuple((sp.sympify(b.mass), sp.sympify(b.inertia)) for b in mechanism.bodies)
    gravity = tuple(sp.sympify(g) for g in mechanism.gravity)
    return names, tuple(params), derived, groups, bodies, gravity


def structure(mechanism: Mechanism, layout: Layout, names: tuple[str, ...]) -> Structure:
    """The structure of `mechanism` for parameters `names` (derived and lambdified on first use)."""
    key = _key(mechanism, layout, names)
    if key in _STRUCTURES:
        return _STRUCTURES[key]
    chain = parameter_chain(mechanism, layout, names)
    symbols = tuple(parameter_symbol(n) for n in mechanism.parameters)
    static: list[sp.Expr] = []
    timed: list[sp.Expr] = []
    shapes = []
    groups = (*layout.constraint_groups, *layout.force_groups)
    for g, ch in zip(groups, (*chain.constraint_groups, *chain.force_groups)):
        sens = sensitivity_of(g)
        nconst, nfun = len(sens.blocks["constants"]), len(sens.blocks["functions"])
        shapes.append((g.size, nconst, nfun))
        static += [c for m in g.constants for c in m] + [e for m in ch.constants for c in m for e in c]
        if nfun:
            timed += [f for m in _series(g) for f in m] + [e for m in ch.functions for f in m for e in f]
    static += [e for b in mechanism.bodies for e in (b.mass, b.mass, b.inertia)]
    static += [e for b in chain.mass for c in b for e in c] + [e for b in chain.weight for g in b for e in g]
    built = Structure(symbols, _lambdify(symbols, static), _lambdify((T, *symbols), timed) if timed else None,
                      tuple(shapes))
    _STRUCTURES[key] = built
    return built
