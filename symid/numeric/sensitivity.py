"""Exact parameter sensitivities of a solved instant, with Phi_q already factored.

Per group of family instances, every residual Jacobian one instant needs
(`symid.symbolic.sensitivity`) comes out of one fused kernel call vectorized
over the members (`sensitivity_build.fused`), and its parameter terms (through
the members' constants and time functions) out of one contraction; the
members' constants, their chain and the masses come from the structure's one
function of the parameter values (`sensitivity_build.structure`: built once
per mechanism structure, so a new parameter value derives and lambdifies
nothing), their time functions and chain from one call per instant. With the
instant's factorization of Phi_q, one solve per parameter and equation
gives q_p, qd_p, qdd_p and (transposed) lam_p for all parameters;
the reactions' derivatives follow explicitly. Backend-independent: any
backend's solved instant (q, qd, qdd, lam) goes in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from symid.numeric.evaluator import Array
from symid.numeric.sensitivity_build import Structure, fused, structure
from symid.numeric.stability import Factor
from symid.symbolic.assemble import Group, Layout
from symid.symbolic.sensitivity import sensitivity_of


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
    """One group: index arrays, its members' constants and their chain."""

    def __init__(self, group: Group) -> None:
        self.group = group
        self.sens = sensitivity_of(group)
        self.n = n = group.size
        roles = group.derived.roles
        # rows of the extended (ng + 3) coordinates of each role's x, y, phi, (3 roles, n): ground's are the 3 zeros
        self.idx = np.concatenate([(3 * group.bodies[r][None, :] + np.arange(3)[:, None]) for r in roles])
        blocks, at = {}, 0
        for name, symbols in self.sens.blocks.items():
            blocks[name] = slice(at, at + len(symbols))
            at += len(symbols)
        self.blocks = blocks
        k = len(self.sens.blocks.get("lam", ()))
        self.rows = group.rows[None, :] + np.arange(k)[:, None]  # (k, n): this group's constraint rows
        self.cf = slice(blocks["constants"].start, blocks["functions"].stop)
        self.const = self.const_p = self.fun = self.fun_p = np.zeros(0)

    def jacobians(self, whats: tuple[str, ...], qx: Array, qdx: Array, qddx: Array, lam: Array | None
                  ) -> tuple[Array, Mapping[str, slice], Array]:
        """The stacked Jacobians `whats` (outputs, nargs, n), their row slices,
        and their parameter terms through constants and time functions (outputs, n, np)."""
        kernel = fused(self.sens, whats)
        args: list = [*qx[self.idx], *qdx[self.idx]]
        if "qdd" in self.blocks:
            args.extend(qddx[self.idx])
        args.extend(self.const)
        args.extend(self.fun)
        if "lam" in self.blocks:
            args.extend(lam[self.rows] if lam is not None else np.zeros(self.rows.shape))
        jac = kernel(args, self.n)
        chain = np.concatenate([self.const_p, self.fun_p])
        return jac, kernel.rows, np.einsum("oan,anp->onp", jac[:, self.cf], chain)

    def times(self, jac: Array, block: str, local: Array) -> Array:
        """J[:, block] times the block's local derivatives (args, n, np) -> (outputs, n, np)."""
        return np.einsum("oan,anp->onp", jac[:, self.blocks[block]], local)


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
        self.built: Structure = structure(mech, layout, self.names)
        self.args = [values[s] for s in self.built.symbols]
        nb = layout.nb
        self._c = [_Part(g) for g in layout.constraint_groups]
        self._f = [_Part(g) for g in layout.force_groups]
        flat = np.array(self.built.static(*self.args), dtype=float).reshape(-1)
        at = 0
        for p, (n, nconst, _) in zip(self._c + self._f, self.built.shapes):
            p.const = flat[at:at + n * nconst].reshape(n, nconst).T
            at += n * nconst
            p.const_p = flat[at:at + n * nconst * nparams].reshape(n, nconst, nparams).transpose(1, 0, 2)
            at += n * nconst * nparams
        self.mass = flat[at:at + 3 * nb]
        at += 3 * nb
        self.mass_p = flat[at:at + 3 * nb * nparams].reshape(3 * nb, nparams)
        at += 3 * nb * nparams
        weight = np.zeros((nb, 3, nparams))
        weight[:, :2] = flat[at:at + 2 * nb * nparams].reshape(nb, 2, nparams)
        self.weight_p = weight.reshape(-1, nparams)
        for p in self._c + self._f:  # no time functions: empty blocks (a timed group sets them per instant)
            nfun = len(p.sens.blocks["functions"])
            p.fun, p.fun_p = np.zeros((nfun, p.n)), np.zeros((nfun, p.n, nparams))
        wanted = set(reactions)
        order = [c.name for c in mech.constraints if c.name in wanted]
        width = {c.name: 3 * len(c.bodies) for c in mech.constraints}
        start, offset = {}, 0
        for name in order:
            start[name] = offset
            offset += width[name]
        self.reaction_size = offset
        self._slots = [(np.array([k for k, n in enumerate(p.group.names) if n in wanted], dtype=np.intp),
                        np.array([start[n] for n in p.group.names if n in wanted], dtype=np.intp))
                       for p in self._c]

    def _timed(self, t: float) -> None:
        """Every group's time functions and their chain at t."""
        if self.built.timed is None:
            return
        flat = np.array(self.built.timed(np.float64(t), *self.args), dtype=float).reshape(-1)
        at, nparams = 0, self.np
        for p, (n, _, nfun) in zip(self._c + self._f, self.built.shapes):
            if not nfun:
                continue
            p.fun = flat[at:at + n * nfun].reshape(n, nfun).T
            at += n * nfun
            p.fun_p = flat[at:at + n * nfun * nparams].reshape(n, nfun, nparams).transpose(1, 0, 2)
            at += n * nfun * nparams

    def _ext(self, v: Array | None) -> Array:
        if v is None:
            return np.zeros(self.layout.ng + 3)
        return np.concatenate([v, np.zeros((3, *v.shape[1:]))])

    def instant(self, factor: Factor, t: float, q: Array, qd: Array | None, qdd: Array | None,
                lam: Array | None, reactions: bool = False) -> Derivatives:
        """The derivatives at the solved instant (statics: qd, qdd None).

        Args:
            factor: the instant's factorization of Phi_q.
            lam: the multipliers, or None (kinematics): then no lam_p.
            reactions: whether to compute the reactions' derivatives.
        """
        ng, nc, nparams = self.layout.ng, self.layout.nc, self.np
        qx, qdx, qddx = self._ext(q), self._ext(qd), self._ext(qdd)
        self._timed(t)
        whats = ("phi",) if self.statics else ("phi", "velocity", "acceleration")
        if lam is not None:
            whats += ("eom", "reactions") if reactions else ("eom",)
        parts = [(p, *p.jacobians(whats, qx, qdx, qddx, lam)) for p in self._c]

        def solve(rhs: Array, transposed: bool = False) -> Array:
            # column by column through the instant's factorization: OpenBLAS's
            # threaded multi-right-hand-side getrs cost ~1 ms a call on a
            # loaded machine, hundreds of times these small single solves
            one = factor.solve_t if transposed else factor.solve
            return np.column_stack([one(rhs[:, k]) for k in range(nparams)])

        def stage(what: str, terms: Sequence[tuple[str, Array]]) -> Array:
            rhs = np.zeros((nc, nparams))
            for p, jac, rows, direct in parts:
                vals = direct[rows[what]]
                for block, ext in terms:
                    vals = vals + p.times(jac[rows[what]], block, ext[p.idx])
                rhs[p.rows] += vals
            return rhs

        q_p = -solve(stage("phi", ()))
        qpx = self._ext(q_p)
        if self.statics:
            qd_p = qdd_p = np.zeros((ng, nparams))
        else:
            qd_p = -solve(stage("velocity", (("q", qpx),)))
            qdd_p = -solve(stage("acceleration", (("q", qpx), ("qd", self._ext(qd_p)))))
        out = Derivatives(q_p, qd_p, qdd_p)
        if lam is None:
            return out
        # d/dp of M qdd + Phi_q^T lam - Q^A, all but Phi_q^T lam_p
        rest = np.zeros((ng + 3, nparams))
        for p, jac, rows, direct in parts:
            e = rows["eom"]
            np.add.at(rest, p.idx, direct[e] + p.times(jac[e], "q", qpx[p.idx]))
        for p in self._f:
            jac, _, direct = p.jacobians(("generalized",), qx, qdx, qddx, None)
            vals = direct + p.times(jac, "q", qpx[p.idx])
            if not self.statics:
                vals = vals + p.times(jac, "qd", self._ext(qd_p)[p.idx])
            np.add.at(rest, p.idx, -vals)
        rest = rest[:ng] - self.weight_p
        if not self.statics:
            rest += self.mass_p * qdd[:, None] + self.mass[:, None] * qdd_p  # type: ignore[index]
        out.lam = lam_p = -solve(rest, transposed=True)
        if reactions:
            lpx = lam_p
            r_p = np.empty((self.reaction_size, nparams))
            for (p, jac, rows, direct), (members, slots) in zip(parts, self._slots):
                if members.size == 0:
                    continue
                r = rows["reactions"]
                vals = direct[r] + p.times(jac[r], "q", qpx[p.idx]) + p.times(jac[r], "lam", lpx[p.rows])
                vals = vals[:, members]  # (outputs, chosen members, np)
                r_p[slots[None, :] + np.arange(vals.shape[0])[:, None]] = vals
            out.reactions = r_p
        return out
