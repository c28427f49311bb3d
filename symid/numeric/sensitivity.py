"""Exact parameter sensitivities of a solved instant, with Phi_q already factored.

Per group of family instances, every residual Jacobian one instant needs
(`symid.symbolic.sensitivity`) comes out of one fused kernel call vectorized
over the members and a chunk of instants at once (`sensitivity_build.fused`: numpy's
cost per operation, not the number of operations, then sets the price), and
its parameter terms (through
the members' constants and time functions) out of one contraction; the
members' constants, their chain and the masses come from the structure's one
function of the parameter values (`sensitivity_build.structure`: built once
per mechanism structure, so a new parameter value derives and lambdifies
nothing), their time functions and chain from one call per chunk. With the
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

from symid.model.friction import has_friction
from symid.numeric.evaluator import Array
from symid.numeric.friction_sensitivity import FrictionSensitivity
from symid.numeric.sensitivity_build import Structure, fused, structure
from symid.numeric.stability import Factor, Scaling
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
    friction: Array | None = None  # (2 nf, np): per joint with friction, d(friction), d(friction_power)


class Stacked:
    """Square Phi_q of K instants, equilibrated by one scaling (as `Factor`),
    solved for all instants and parameters in one batched call."""

    def __init__(self, jac: Array, scaling: Scaling) -> None:
        self.dr, self.dc = scaling.dr[:, None, None], scaling.dc[:, None, None]
        self.a = jac * scaling.dr[:, None] * scaling.dc  # (K, n, n)

    def solve(self, rhs: Array, transposed: bool = False) -> Array:
        """(n, K, np) -> x (n, K, np) with Phi_q x = rhs (transposed: Phi_q^T x = rhs) at each instant."""
        left, right = (self.dc, self.dr) if transposed else (self.dr, self.dc)
        a = self.a.transpose(0, 2, 1) if transposed else self.a
        return right * np.linalg.solve(a, (left * rhs).transpose(1, 0, 2)).transpose(1, 0, 2)


def _pad(v: Array) -> Array:
    """(ng, ...) -> the extended (ng + 3, ...): ground's three zero rows appended."""
    return np.concatenate([v, np.zeros((3, *v.shape[1:]))])


class _Part:
    """One group: index arrays, its members' constants and their chain.

    Arrays over members and instants flatten them member-major: (..., n * K).
    """

    def __init__(self, group: Group) -> None:
        self.group = group
        self.sens = sensitivity_of(group)
        self.n = group.size
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
        self.nfun = len(self.sens.blocks["functions"])
        self.const: Array = np.zeros(0)  # (nconst, n), set by the evaluator
        self.const_p: Array = np.zeros(0)  # (nconst, n, np), set by the evaluator
        self.fun: Array = np.zeros(0)  # (nfun, n, K), set per chunk
        self.fun_p: Array = np.zeros(0)  # (nfun, n, K, np), set per chunk

    def local(self, ext: Array) -> Array:
        """The members' rows of an extended (ng + 3, K, ...) array: (3 roles, n * K, ...)."""
        v = ext[self.idx]
        return v.reshape(v.shape[0], v.shape[1] * v.shape[2], *v.shape[3:])

    def jacobians(self, whats: tuple[str, ...], qx: Array, qdx: Array, qddx: Array, lam: Array | None
                  ) -> tuple[Array, Mapping[str, slice], Array]:
        """The stacked Jacobians `whats` (outputs, nargs, n * K), their row
        slices, and their parameter terms through constants and time
        functions (outputs, n * K, np); qx etc. (ng + 3, K), lam (nc, K)."""
        kernel = fused(self.sens, whats)
        count = qx.shape[1]
        args: list = [*self.local(qx), *self.local(qdx)]
        if "qdd" in self.blocks:
            args.extend(self.local(qddx))
        args.extend(np.repeat(self.const, count, axis=1))
        width = self.n * count
        args.extend(self.fun.reshape(self.nfun, width))
        if "lam" in self.blocks:
            rows = self.rows.shape
            args.extend(lam[self.rows].reshape(rows[0], width) if lam is not None else np.zeros((rows[0], width)))
        jac = kernel(args, width)
        chain = np.concatenate([np.repeat(self.const_p, count, axis=1), self.fun_p.reshape(self.nfun, width, self.const_p.shape[-1])])
        return jac, kernel.rows, np.einsum("oam,amp->omp", jac[:, self.cf], chain)

    def times(self, jac: Array, block: str, local: Array) -> Array:
        """J[:, block] times the block's local derivatives (args, n * K, np) -> (outputs, n * K, np)."""
        return np.einsum("oam,amp->omp", jac[:, self.blocks[block]], local)

    def unflat(self, vals: Array) -> Array:
        """(outputs, n * K, np) -> (outputs, n, K, np)."""
        return vals.reshape(vals.shape[0], self.n, vals.shape[1] // self.n, vals.shape[-1])


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
        wanted = set(reactions)
        start, self.reaction_size = mech.reaction_starts(wanted)
        self._start = start
        # joint friction (inverse dynamics only: statics has none)
        self.friction = None if statics or not any(has_friction(c) for c in mech.constraints) \
            else FrictionSensitivity(layout, values, self.names)
        self._slots = [(np.array([k for k, n in enumerate(p.group.names) if n in wanted], dtype=np.intp),
                        np.array([start[n] for n in p.group.names if n in wanted], dtype=np.intp))
                       for p in self._c]

    def _timed(self, ts: Array) -> None:
        """Every group's time functions and their chain at the instants ts (K,)."""
        count, nparams = ts.size, self.np
        for p in self._c + self._f:  # a group without time functions: empty blocks
            p.fun, p.fun_p = np.zeros((p.nfun, p.n, count)), np.zeros((p.nfun, p.n, count, nparams))
        if self.built.timed is None:
            return
        # a numpy t: a pole or a domain error gives inf or NaN, never an exception
        vals = self.built.timed(np.asarray(ts, dtype=np.float64), *self.args)
        flat = np.empty((len(vals), count))
        for k, v in enumerate(vals):  # entries free of t come out scalars: the assignment broadcasts them
            flat[k] = v
        at = 0
        for p, (n, _, nfun) in zip(self._c + self._f, self.built.shapes):
            if not nfun:
                continue
            p.fun = flat[at:at + n * nfun].reshape(n, nfun, count).transpose(1, 0, 2)
            at += n * nfun
            p.fun_p = flat[at:at + n * nfun * nparams].reshape(n, nfun, nparams, count).transpose(1, 0, 3, 2)
            at += n * nfun * nparams

    def _ext(self, v: Array | None, count: int) -> Array:
        """(K, ng, ...) instants' values -> the extended (ng + 3, K, ...) (None: zeros)."""
        if v is None:
            return np.zeros((self.layout.ng + 3, count))
        return _pad(np.moveaxis(v, 0, 1))

    def instant(self, factor: Factor, t: float, q: Array, qd: Array | None, qdd: Array | None,
                lam: Array | None, reactions: bool = False) -> Derivatives:
        """The derivatives at one solved instant (statics: qd, qdd None); see `chunk`."""
        rows = None if lam is None else lam[None]
        d = self.chunk([factor], np.array([t]), q[None], None if qd is None else qd[None],
                       None if qdd is None else qdd[None], rows, reactions)
        return Derivatives(d.q[:, 0], d.qd[:, 0], d.qdd[:, 0], None if d.lam is None else d.lam[:, 0],
                           None if d.reactions is None else d.reactions[:, 0],
                           None if d.friction is None else d.friction[:, 0])

    def chunk(self, factors: Sequence[Factor] | Stacked, ts: Array, q: Array, qd: Array | None, qdd: Array | None,
              lam: Array | None, reactions: bool = False) -> Derivatives:
        """The derivatives at K solved instants, vectorized over them: each
        array of `Derivatives` with the instants as its middle axis (rows, K, np).

        Args:
            factors: each instant's factorization of Phi_q (K), or their Phi_q stacked.
            ts: (K,); q, qd, qdd: (K, ng) (statics: qd, qdd None).
            lam: (K, nc) multipliers, or None (kinematics): then no lam_p.
            reactions: whether to compute the reactions' derivatives.
        """
        ng, nc, nparams, count = self.layout.ng, self.layout.nc, self.np, ts.size
        qx, qdx, qddx = self._ext(q, count), self._ext(qd, count), self._ext(qdd, count)
        lamx = None if lam is None else lam.T
        self._timed(ts)
        whats: tuple[str, ...] = ("phi",) if self.statics else ("phi", "velocity", "acceleration")
        if lam is not None:
            whats += ("eom", "reactions") if reactions else ("eom",)
        parts = [(p, *p.jacobians(whats, qx, qdx, qddx, lamx)) for p in self._c]

        def solve(rhs: Array, transposed: bool = False) -> Array:
            """(n, K, np) -> (m, K, np), instant by instant and column by column
            through each instant's factorization: OpenBLAS's threaded
            multi-right-hand-side getrs took ~1 ms a call on a loaded machine,
            hundreds of times these small single solves."""
            if isinstance(factors, Stacked):
                return factors.solve(rhs, transposed)
            out = [[(f.solve_t if transposed else f.solve)(rhs[:, k, j]) for j in range(rhs.shape[2])]
                   for k, f in enumerate(factors)]
            return np.array(out).transpose(2, 0, 1)

        def stage(what: str, terms: Sequence[tuple[str, Array]]) -> Array:
            rhs = np.zeros((nc, count, nparams))
            for p, jac, rows, direct in parts:
                vals = direct[rows[what]]
                for block, ext in terms:
                    vals = vals + p.times(jac[rows[what]], block, p.local(ext))
                rhs[p.rows] += p.unflat(vals)
            return rhs

        q_p = -solve(stage("phi", ()))
        qpx = _pad(q_p)
        qd_p = qdd_p = np.zeros((ng, count, nparams))
        if not self.statics:
            qd_p = -solve(stage("velocity", (("q", qpx),)))
            qdd_p = -solve(stage("acceleration", (("q", qpx), ("qd", _pad(qd_p)))))
        lam_p = r_p = fr_p = None
        if lam is not None:
            # d/dp of M qdd + Phi_q^T lam - Q^A, all but Phi_q^T lam_p: (ng + 3, K, np)
            rest = np.zeros((ng + 3, count, nparams))
            for p, jac, rows, direct in parts:
                e = rows["eom"]
                np.add.at(rest, p.idx, p.unflat(direct[e] + p.times(jac[e], "q", p.local(qpx))))
            qdpx = _pad(qd_p)
            for p in self._f:
                jac, _, direct = p.jacobians(("generalized",), qx, qdx, qddx, None)
                vals = direct + p.times(jac, "q", p.local(qpx))
                if not self.statics:
                    vals = vals + p.times(jac, "qd", p.local(qdpx))
                np.add.at(rest, p.idx, -p.unflat(vals))
            rest = rest[:ng] - self.weight_p[:, None, :]
            if not self.statics:
                rest += self.mass_p[:, None, :] * qdd.T[:, :, None] + self.mass[:, None, None] * qdd_p  # type: ignore[union-attr]
            fr = self.friction
            if fr is None:
                lam_p = -solve(rest, transposed=True)
            else:  # the converged friction equations differentiated (symid.numeric.friction_sensitivity)
                def const(g: int, m: int) -> tuple[Array, Array]:
                    return self._c[g].const[:, m], self._c[g].const_p[:, m, :]

                lam_p = fr.solve(qx, qdx, lamx, qpx, qdpx, const, rest,  # type: ignore[arg-type]
                                 lambda rhs: solve(rhs, transposed=True))[0]
                fr_p = fr.columns()
            if reactions:
                r_p = np.empty((self.reaction_size, count, nparams))
                lpx = lam_p
                for (p, jac, rows, direct), (members, slots) in zip(parts, self._slots):
                    if members.size == 0:
                        continue
                    r = rows["reactions"]
                    lam_local = lpx[p.rows].reshape(p.rows.shape[0], p.n * count, nparams)
                    vals = direct[r] + p.times(jac[r], "q", p.local(qpx)) + p.times(jac[r], "lam", lam_local)
                    r_p[slots[None, :] + np.arange(vals.shape[0])[:, None]] = p.unflat(vals)[:, members]
                if fr is not None:  # each joint's friction loads
                    fr.reactions(r_p, self._start)
        return Derivatives(q_p, qd_p, qdd_p, lam_p, r_p, fr_p)
