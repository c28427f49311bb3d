"""Exact parameter sensitivities of a solved instant, with Phi_q already factored.

The residual Jacobians of every family (`symid.symbolic.sensitivity`) are
lambdified once and evaluated vectorized over a group's members, as the
reference evaluator does; the chain from base parameters into the members'
constants and time functions is evaluated once per run (constants) or per
instant (time functions). With the instant's factorization of Phi_q, one
solve per parameter and equation gives q_p, qd_p, qdd_p and (transposed)
lam_p; the reactions' derivatives follow explicitly. Backend-independent:
any backend's solved instant (q, qd, qdd, lam) goes in.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.model.params import to_float
from symid.numeric.evaluator import Array
from symid.numeric.reference import _GroupData, _stack, _time_function
from symid.numeric.stability import Factor
from symid.symbolic.assemble import Layout
from symid.symbolic.sensitivity import (ConstraintSensitivity, ForceSensitivity, GroupChain, parameter_chain,
                                        sensitivity_of)


@cache
def _kernel(sens: ConstraintSensitivity | ForceSensitivity, what: str) -> Callable[..., list]:
    """One Jacobian of a family, lambdified over its local arguments (cached per family)."""
    matrix = getattr(sens, what)
    return sp.lambdify(list(sens.args), list(matrix), modules="numpy", cse=True)


@dataclass
class Derivatives:
    """d(solved quantity)/d(parameters) at one instant, one column per parameter.

    Sizes: q, qd, qdd: (ng, np); lam: (nc, np); reactions: (len of the
    evaluator's reactions, np); None where not asked for.
    """

    q: Array
    qd: Array
    qdd: Array
    lam: Array | None = None
    reactions: Array | None = None


class _Part:
    """One group's numbers: its values (through the reference evaluator's
    group data) and the chain of its constants and time functions."""

    def __init__(self, data: _GroupData, chain: GroupChain, values: Mapping[sp.Symbol, float], nparams: int) -> None:
        self.data = data
        self.sens = sensitivity_of(data.group)
        n = data.group.size
        self.n, self.np = n, nparams
        self.nconst = len(self.sens.blocks["constants"])
        self.nfun = len(self.sens.blocks["functions"])
        self.const_p = np.array([[[to_float(e, values) for e in c] for c in m] for m in chain.constants],
                                dtype=float).reshape(n, self.nconst, nparams).transpose(1, 2, 0)
        flat = [e for m in chain.functions for f in m for e in f]
        self._fun_p = _time_function(flat, values) if flat else None

    def fun_p(self, t: float) -> Array:
        """(functions, np, members) at t."""
        if self._fun_p is None:
            return np.zeros((self.nfun, self.np, self.n))
        return self._fun_p(t).reshape(self.n, self.nfun, self.np).transpose(1, 2, 0)

    def local(self, ext: Array) -> Array:
        """A global (ng + 3, ...) array's rows of each role: (3 roles, ..., members)."""
        return np.concatenate([np.moveaxis(ext[self.data.cols[r]], 0, -1).reshape(3, *ext.shape[1:], self.n)
                               for r in self.data.roles])

    def jacobian(self, what: str, qx: Array, qdx: Array, qddx: Array, lam: Array | None, t: float) -> Array:
        """The Jacobian `what` at the instant, (outputs, nargs, members)."""
        d = self.data
        args: list = [*self.local(qx), *self.local(qdx)]
        if "qdd" in self.sens.blocks:
            args.extend(self.local(qddx))
        args.extend(d.constants)
        if d.functions is not None:
            args.extend(d.functions(t).reshape(d.width, self.n))
        if "lam" in self.sens.blocks:
            args.extend(self.member_rows(lam) if lam is not None else np.zeros((len(self.sens.blocks["lam"]), self.n)))
        values = _stack(_kernel(self.sens, what)(*args), self.n)
        return values.reshape(-1, len(self.sens.args), self.n)

    def member_rows(self, rows: Array) -> Array:
        """A (nc, ...) array's rows of each member: (rows, ..., members)."""
        k = len(self.sens.blocks["lam"])
        picked = rows[self.data.group.rows[None, :] + np.arange(k)[:, None]]  # (k, n, ...)
        return np.moveaxis(picked, 1, -1)

    def chained(self, what: str, jac: Array, q_p: Array | None, qd_p: Array | None, qdd_p: Array | None,
                lam_p: Array | None, t: float) -> Array:
        """J times the local derivatives (None: an unknown, left out), (outputs, np, members)."""
        zeros = np.zeros((len(self.sens.blocks["q"]), self.np, self.n))
        parts = [zeros if q_p is None else self.local(q_p), zeros if qd_p is None else self.local(qd_p)]
        if "qdd" in self.sens.blocks:
            parts.append(zeros if qdd_p is None else self.local(qdd_p))
        parts += [self.const_p, self.fun_p(t)]
        if "lam" in self.sens.blocks:
            k = len(self.sens.blocks["lam"])
            parts.append(np.zeros((k, self.np, self.n)) if lam_p is None else self.member_rows(lam_p))
        return np.einsum("oan,apn->opn", jac, np.concatenate(parts))

    def add_rows(self, out: Array, vals: Array) -> None:
        """Add (rows, np, members) into the constraint rows of `out` (nc, np)."""
        k = vals.shape[0]
        out[self.data.group.rows[None, :] + np.arange(k)[:, None]] += vals.transpose(0, 2, 1)

    def add_columns(self, out: Array, vals: Array) -> None:
        """Add (3 roles, np, members) into the coordinates of `out` (ng + 3, np)."""
        for r, role in enumerate(self.data.roles):
            np.add.at(out, self.data.cols[role], vals[3 * r:3 * r + 3].transpose(2, 0, 1))


class SensitivityEvaluator:
    """The sensitivities of one mechanism's instants to base parameters `names`.

    Args:
        layout, values: the mechanism laid out, every parameter's value.
        names: base parameters, in column order.
        statics: qd = qdd = 0 and forces at rest.
        reactions: constraints whose reactions are output (file order), as the evaluator's.
    """

    def __init__(self, layout: Layout, values: Mapping[sp.Symbol, float], names: Sequence[str], statics: bool,
                 reactions: tuple[str, ...]) -> None:
        mech = layout.mechanism
        self.layout, self.names, self.statics = layout, tuple(names), statics
        self.np = nparams = len(names)
        chain = parameter_chain(mech, layout, names)
        nb = layout.nb
        self._c = [_Part(_GroupData(g, values, nb, series=True), ch, values, nparams)
                   for g, ch in zip(layout.constraint_groups, chain.constraint_groups)]
        self._f = [_Part(_GroupData(g, values, nb, series=False), ch, values, nparams)
                   for g, ch in zip(layout.force_groups, chain.force_groups)]
        self.mass = np.array([[to_float(b.mass, values)] * 2 + [to_float(b.inertia, values)]
                              for b in mech.bodies]).reshape(-1)
        self.mass_p = np.array([[[to_float(e, values) for e in c] for c in b] for b in chain.mass]).reshape(-1, nparams)
        weight = np.zeros((nb, 3, nparams))
        weight[:, :2] = np.array([[[to_float(e, values) for e in g] for g in b] for b in chain.weight]).reshape(nb, 2, -1)
        self.weight_p = weight.reshape(-1, nparams)
        wanted = set(reactions)
        start, self.reaction_size = mech.reaction_starts(wanted)
        self._slots = [(np.array([k for k, n in enumerate(p.data.group.names) if n in wanted], dtype=np.intp),
                        np.array([start[n] for n in p.data.group.names if n in wanted], dtype=np.intp))
                       for p in self._c]

    def _ext(self, v: Array | None, width: int | None = None) -> Array:
        ng = self.layout.ng
        if v is None:
            return np.zeros(ng + 3) if width is None else np.zeros((ng + 3, width))
        return np.concatenate([v, np.zeros((3, *v.shape[1:]))])

    def _rows(self, what: str, state: tuple[Array, Array, Array, Array | None],
              known: tuple[Array | None, Array | None, Array | None, Array | None], t: float) -> Array:
        out = np.zeros((self.layout.nc, self.np))
        for p in self._c:
            p.add_rows(out, p.chained(what, p.jacobian(what, *state, t), *known, t))
        return out

    def instant(self, factor: Factor, t: float, q: Array, qd: Array | None, qdd: Array | None,
                lam: Array | None, reactions: bool = False) -> Derivatives:
        """The derivatives at the solved instant (statics: qd, qdd None).

        Args:
            factor: the instant's factorization of Phi_q.
            lam: the multipliers, or None (kinematics): then no lam_p.
            reactions: whether to compute the reactions' derivatives.
        """
        ng, nparams = self.layout.ng, self.np
        qx, qdx, qddx = self._ext(q), self._ext(qd), self._ext(qdd)
        state = (qx, qdx, qddx, lam)

        def solve(rhs: Array, transposed: bool = False) -> Array:
            one = factor.solve_t if transposed else factor.solve
            return np.column_stack([one(rhs[:, k]) for k in range(nparams)]) if nparams else rhs[:0]

        q_p = -solve(self._rows("phi", state, (None, None, None, None), t))
        qpx = self._ext(q_p)
        if self.statics:
            qd_p = qdd_p = np.zeros((ng, nparams))
        else:
            qd_p = -solve(self._rows("velocity", state, (qpx, None, None, None), t))
            qdd_p = -solve(self._rows("acceleration", state, (qpx, self._ext(qd_p), None, None), t))
        out = Derivatives(q_p, qd_p, qdd_p)
        if lam is None:
            return out
        qdpx = self._ext(qd_p)
        # d/dp of M qdd + Phi_q^T lam - Q^A, all but Phi_q^T lam_p
        rest = np.zeros((ng + 3, nparams))
        for p in self._c:
            p.add_columns(rest, p.chained("eom", p.jacobian("eom", *state, t), qpx, None, None, None, t))
        for p in self._f:
            jac = p.jacobian("generalized", qx, qdx, qddx, None, t)
            p.add_columns(rest, -p.chained("generalized", jac, qpx, None if self.statics else qdpx, None, None, t))
        rest = rest[:ng] - self.weight_p
        if not self.statics:
            rest += self.mass_p * qdd[:, None] + self.mass[:, None] * qdd_p  # type: ignore[index]
        out.lam = lam_p = -solve(rest, transposed=True)
        if reactions:
            r_p = np.empty((self.reaction_size, nparams))
            for p, (members, slots) in zip(self._c, self._slots):
                if members.size == 0:
                    continue
                vals = p.chained("reactions", p.jacobian("reactions", *state, t), qpx, None, None, lam_p, t)
                vals = vals[:, :, members]  # (outputs, np, chosen members)
                r_p[slots[None, :] + np.arange(vals.shape[0])[:, None]] = vals.transpose(0, 2, 1)
            out.reactions = r_p
        return out
