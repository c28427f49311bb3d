"""The reference evaluator (the core implementation): each family's expressions lambdified once and
evaluated vectorized over all members of a group."""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.symbolic import symbols as s
from symid.symbolic.assemble import Group, Layout
from symid.numeric.evaluator import Array, Capabilities, Needs
from symid.symbolic.derive import DerivedConstraint, DerivedForce, total_derivative
from symid.model.mechanism import T
from symid.symbolic.rounding import grouped
from symid.model.params import to_float

if TYPE_CHECKING:
    from symid.numeric.friction import FrictionModel


def _arguments(derived: DerivedConstraint | DerivedForce) -> list[sp.Symbol]:
    """The one calling convention of every kernel of a family."""
    args: list[sp.Symbol] = []
    for role in derived.roles:
        args.extend(s.q(role))
    for role in derived.roles:
        args.extend(s.qd(role))
    args.extend(derived.constants)
    args.extend(derived.functions)
    if isinstance(derived, DerivedConstraint):
        args.extend(derived.lam)
    return args


@cache
def _kernel(derived: DerivedConstraint | DerivedForce, what: str, static: bool = False,
            ground: str | None = None) -> Callable[..., list]:
    """Lambdify one list of a family's expressions (cached per family, kind
    and ground role). For members joined to ground the ground role's
    coordinates are substituted (zeros) first, so that `grouped` sees its
    fixed point as the trig-free offset it is."""
    if isinstance(derived, DerivedConstraint):
        exprs = {
            "phi": list(derived.phi),
            "phi_q": [e for role in derived.roles for e in derived.jac[role]],
            "nu": list(derived.nu),
            "gamma": list(derived.gamma),
            "reactions": [e for role in derived.roles for e in derived.reactions[role]],
        }[what]
    else:
        source = derived.generalized if what == "applied" else derived.loads
        exprs = [e for role in derived.roles for e in source[role]]
        if static:
            exprs = [e.subs({v: 0 for role in derived.roles for v in s.qd(role)}) for e in exprs]
    if ground is not None:
        exprs = [sp.sympify(e).xreplace({v: 0 for v in (*s.q(ground), *s.qd(ground))}) for e in exprs]
    # a module object: lambdify then imports nothing ("numpy" runs `from numpy import *`, which
    # loads numpy.ma, numpy.testing, numpy.f2py...: a fifth of a second of a cold build)
    return sp.lambdify(_arguments(derived), [grouped(e) for e in exprs], modules=[np], cse=True)


def _time_function(exprs: Sequence[sp.Expr], values: Mapping[sp.Symbol, float]) -> Callable[[float], Array]:
    """t -> array of the expressions' values (parameters substituted)."""
    numeric = [sp.sympify(e).xreplace({k: sp.Float(v, 17) for k, v in values.items()}) for e in exprs]
    fn = sp.lambdify([T], numeric, modules=[np])  # a module object: no namespace scan
    count = len(numeric)
    # a numpy t: a pole or a domain error gives inf or NaN (checked by the
    # run), never a Python exception out of the lambdified code
    return lambda t: np.array(fn(np.float64(t)), dtype=float).reshape(count)


class _GroupData:
    """Numbers of one group: constants, time functions and index arrays."""

    def __init__(self, group: Group, values: Mapping[sp.Symbol, float], nb: int, series: bool) -> None:
        self.group = group
        n = group.size
        self.roles = group.derived.roles
        consts = [[to_float(c, values) for c in member] for member in group.constants]
        self.constants = np.array(consts, dtype=float).reshape(n, -1).T
        per_member = [list(f) for f in group.functions]
        width = len(per_member[0]) if per_member else 0
        if series and width:
            # f, f', f'' of every member, flattened row-major: (3, n)
            exprs = [sp.diff(fm[0], T, order) for order in range(3) for fm in per_member]
            width = 3
        else:
            exprs = [fm[c] for c in range(width) for fm in per_member]
        self.functions = _time_function(exprs, values) if width else None
        self.width = width
        self.cols = {role: 3 * group.bodies[role][:, None] + np.arange(3)[None, :] for role in self.roles}
        # members by the role that is ground (None: none is)
        ground = [next((r for r in self.roles if group.bodies[r][m] == nb), None) for m in range(n)]
        self.parts = [(np.array([m for m in range(n) if ground[m] == r], dtype=np.intp), r)
                      for r in dict.fromkeys(ground)]

    def evaluate(self, what: str, args: list, members: Array | None = None, static: bool = False) -> Array:
        """A kernel's values for the members (all: None), shape (len, members):
        each part of the members through its own ground variant."""
        wanted = np.arange(self.group.size) if members is None else members
        out: Array | None = None
        for part, ground in self.parts:
            pick = part if members is None else np.intersect1d(part, wanted, assume_unique=True)  # both sorted
            if pick.size == 0:
                continue
            everything = pick.size == self.group.size
            sub = args if everything else [a[pick] if np.ndim(a) else a for a in args]
            vals = _stack(_kernel(self.group.derived, what, static, ground)(*sub), pick.size)
            if pick.size == wanted.size:
                return vals
            if out is None:
                out = np.empty((vals.shape[0], wanted.size))
            out[:, np.searchsorted(wanted, pick)] = vals
        assert out is not None
        return out

    def args(self, qx: Array, qdx: Array | None, t: float, lam: Array | None = None) -> list:
        n = self.group.size
        out: list = []
        for role in self.roles:
            out.extend(qx[self.cols[role]].T)
        for role in self.roles:
            out.extend(qdx[self.cols[role]].T if qdx is not None else np.zeros((3, n)))
        out.extend(self.constants)
        if self.functions is not None:
            out.extend(self.functions(t).reshape(self.width, n))
        if lam is not None:
            out.extend(lam)
        elif isinstance(self.group.derived, DerivedConstraint):
            out.extend(np.zeros((len(self.group.derived.lam), n)))
        return out


def _stack(values: list, n: int) -> Array:
    """Kernel outputs (arrays or scalar constants) as one (len, n) array (each
    row assigned in place: a constant broadcasts, an array is copied)."""
    out = np.empty((len(values), n))
    for k, v in enumerate(values):
        out[k] = v
    return out


class ReferenceEvaluator:
    """Evaluator for a layout with numeric parameter values (`friction`: the
    joint friction model the Python loop solves with, None without)."""

    capabilities = Capabilities()  # the shared Python loop's: built per variant, no loop of its own

    def __init__(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                 friction: FrictionModel | None = None) -> None:
        self.layout = layout
        self.needs = needs
        self.friction = friction
        mech = layout.mechanism
        nb = layout.nb
        self._cgroups = [_GroupData(g, values, nb, series=True) for g in layout.constraint_groups]
        self._fgroups = [_GroupData(g, values, nb, series=False) for g in layout.force_groups]
        masses = np.array([[to_float(b.mass, values)] * 2 + [to_float(b.inertia, values)] for b in mech.bodies])
        self._mass = masses.reshape(-1)
        gravity = np.array([to_float(g, values) for g in mech.gravity])
        with np.errstate(all="ignore"):  # a weight beyond the doubles: inf, reported by the run
            self._gravity = (masses[:, :2] * gravity[None, :]).reshape(nb, 2)
        wanted = set(needs.reactions)
        self._reaction_members = [
            np.array([k for k, name in enumerate(g.group.names) if name in wanted], dtype=np.intp)
            for g in self._cgroups
        ]
        # output slots of each requested constraint's reaction, in file order
        start, self._reaction_size = mech.reaction_starts(wanted)
        self._reaction_slots = [
            np.array([start[g.group.names[k]] for k in members], dtype=np.intp)
            for g, members in zip(self._cgroups, self._reaction_members)
        ]

    @staticmethod
    def _extend(q: Array) -> Array:
        """q with ground's three zero coordinates appended (index nb)."""
        return np.concatenate([q, np.zeros(3)])

    def _rows(self, what: str, q: Array, qd: Array | None, t: float) -> Array:
        out = np.empty(self.layout.nc)
        qx = self._extend(q)
        qdx = self._extend(qd) if qd is not None else None
        for g in self._cgroups:
            derived = g.group.derived
            vals = g.evaluate(what, g.args(qx, qdx, t))
            rows = derived.family.rows  # type: ignore[union-attr]
            out[g.group.rows[None, :] + np.arange(rows)[:, None]] = vals
        return out

    def phi(self, q: Array, t: float) -> Array:
        return self._rows("phi", q, None, t)

    def nu(self, q: Array, t: float) -> Array:
        return self._rows("nu", q, None, t)

    def gamma(self, q: Array, qd: Array, t: float) -> Array:
        return self._rows("gamma", q, qd, t)

    def phi_q(self, q: Array, t: float) -> Array:
        nc, ng = self.layout.nc, self.layout.ng
        out = np.zeros((nc, ng + 3))
        qx = self._extend(q)
        for g in self._cgroups:
            derived = g.group.derived
            n, rows = g.group.size, derived.family.rows  # type: ignore[union-attr]
            vals = g.evaluate("phi_q", g.args(qx, None, t)).reshape(len(g.roles), rows, 3, n)
            for r, role in enumerate(g.roles):
                row_idx = g.group.rows[None, None, :] + np.arange(rows)[:, None, None]
                col_idx = g.cols[role].T[None, :, :]
                out[row_idx, col_idx] = vals[r]
        return out[:, :ng]

    def phi_q_sparse(self, q: Array, t: float):  # type: ignore[no-untyped-def]
        from scipy import sparse

        rows, cols, values = self.phi_q_entries(q, t)
        return sparse.csc_matrix((values, (rows, cols)), shape=(self.layout.nc, self.layout.ng))

    def phi_q_entries(self, q: Array, t: float) -> tuple[Array, Array, Array]:
        """Phi_q's entries as (rows, cols, values), ground's columns left out:
        what phi_q fills, with nothing nc x ng (large mechanisms' setup)."""
        ng = self.layout.ng
        qx = self._extend(q)
        parts: list[tuple[Array, Array, Array]] = []
        for g in self._cgroups:
            derived = g.group.derived
            n, rows = g.group.size, derived.family.rows  # type: ignore[union-attr]
            vals = g.evaluate("phi_q", g.args(qx, None, t)).reshape(len(g.roles), rows, 3, n)
            for r, role in enumerate(g.roles):
                row_idx = np.broadcast_to(g.group.rows[None, None, :] + np.arange(rows)[:, None, None], vals[r].shape)
                col_idx = np.broadcast_to(g.cols[role].T[None, :, :], vals[r].shape)
                keep = col_idx < ng
                parts.append((row_idx[keep], col_idx[keep], vals[r][keep]))
        if not parts:
            empty = np.zeros(0)
            return empty.astype(np.intp), empty.astype(np.intp), empty
        return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))  # type: ignore[return-value]

    def applied(self, q: Array, qd: Array | None, t: float) -> Array:
        nb = self.layout.nb
        out = np.zeros(3 * (nb + 1))
        out[: 3 * nb].reshape(nb, 3)[:, :2] += self._gravity
        qx = self._extend(q)
        qdx = self._extend(qd) if qd is not None and self.needs.velocity else None
        for g in self._fgroups:
            vals = g.evaluate("applied", g.args(qx, qdx, t), static=qdx is None).reshape(len(g.roles), 3, -1)
            for r, role in enumerate(g.roles):
                np.add.at(out, g.cols[role].T, vals[r])
        return out[: 3 * nb]

    def mass(self) -> Array:
        return self._mass

    def reactions(self, q: Array, lam: Array, t: float) -> Array:
        out = np.empty(self._reaction_size)
        qx = self._extend(q)
        for g, members, slots in zip(self._cgroups, self._reaction_members, self._reaction_slots):
            if members.size == 0:
                continue
            derived = g.group.derived
            rows = derived.family.rows  # type: ignore[union-attr]
            vals = g.evaluate("reactions", g.args(qx, None, t, lam[g.group.rows[None, :] + np.arange(rows)[:, None]]),
                              members)
            out[slots[None, :] + np.arange(vals.shape[0])[:, None]] = vals
        return out

    def nonfinite_elements(self, q: Array, qd: Array | None, qdd: Array | None, t: float,
                           loads: bool = True) -> list[str]:
        """The elements with a non-finite value at (q, qd, t), as "kind name"
        in file order within each kind: constraints (Phi, Phi_q, nu, gamma),
        forces (their generalized forces), bodies (mass, inertia, weight,
        mass * qdd); without `loads` (a kinematic quantity failed) constraints
        only."""
        qx = self._extend(q)
        qdx = self._extend(qd) if qd is not None else None
        bad: list[str] = []
        for g in self._cgroups:
            whats = ["phi", "phi_q"] + (["nu"] if self.needs.velocity else [])
            whats += ["gamma"] if qdx is not None else []
            for what in whats:
                vals = g.evaluate(what, g.args(qx, qdx if what == "gamma" else None, t))
                bad += [g.group.names[m] for m in np.flatnonzero(~np.isfinite(vals).all(axis=0))]
        mech = self.layout.mechanism
        if not loads:
            return [f"constraint {c.name}" for c in mech.constraints if c.name in bad]
        for g in self._fgroups:
            vals = g.evaluate("applied", g.args(qx, qdx, t), static=qdx is None)
            bad += [g.group.names[m] for m in np.flatnonzero(~np.isfinite(vals).all(axis=0))]
        inertial = self._mass.reshape(-1, 3)
        load = np.concatenate([self._gravity, inertial], axis=1)
        if qdd is not None:
            load = np.concatenate([load, (self._mass * qdd).reshape(-1, 3)], axis=1)
        bad += [b.name for b, ok in zip(mech.bodies, np.isfinite(load).all(axis=1)) if not ok]
        kinds = [*(("constraint", c.name) for c in mech.constraints), *(("force", f.name) for f in mech.forces),
                 *(("body", b.name) for b in mech.bodies)]
        return [f"{kind} {name}" for kind, name in kinds if name in bad]
