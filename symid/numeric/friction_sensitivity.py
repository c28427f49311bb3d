"""Parameter sensitivities of the multipliers, reactions and friction columns
when joints carry friction (contract v1.1, "Sensitivities" and "Joint friction").

With friction the equations of motion are `M qdd + Phi_q^T lam - Q^A - G f = 0`
and each joint's friction `f_k = F_k(q, qd, lam, p) = -(c s(speed) N + viscous speed)`
is solved with lam at each instant (`symid.numeric.friction`). The converged
equations, not the iterations, are differentiated: with `rest` the derivative
of everything but `Phi_q^T lam - G f` (as without friction), `y = f_p`,

    Phi_q^T lam_p = -rest + G_p f + G y,    y = F_p + F_lam lam_p

(`G_p`, `F_p` through q_p, qd_p, the joints' constants and the friction keys
mu, radius, viscous, arm, v_smooth; `F_lam = -c s dN/dlam`). With
`A = (Phi_q^T)^-1 (-rest + G_p f)` and `X = (Phi_q^T)^-1 G` (the solve's own
Sherman-Morrison-Woodbury split), `(I - F_lam X) y = F_p + F_lam A` and
`lam_p = A + X y`. The reaction columns add `L_p f + L y` (L: a unit
friction's loads), the friction columns are `y` and `y speed + f speed_p`.
The sign s = tanh(speed / v_smooth) has `s_p = (1 - s^2)(speed_p / v_smooth
- speed v_smooth_p / v_smooth^2)`; the exact sign (v_smooth = 0) has none.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.model.friction import coulomb_arm, has_friction, inverse_arm
from symid.model.mechanism import parameter_symbol
from symid.model.params import to_float
from symid.numeric.evaluator import Array
from symid.symbolic import symbols as s
from symid.symbolic.assemble import Layout
from symid.symbolic.friction import ARM_INV, derive_friction
from symid.symbolic.sensitivity import expand_derived

# the friction keys whose parameter derivatives enter: per joint, in this order
KEYS = ("coulomb", "viscous", "v_smooth", "arm_inv")


@dataclass(frozen=True, eq=False)
class _Family:
    """One family's friction values and their Jacobian by its local arguments.

    Attributes:
        nargs: q_i, q_j, qd_i, qd_j (12), constants, multipliers, arm_inv.
        nconst, rows: how many constants and multipliers.
        fn: local arguments -> [values (14): speed, N, G_i, G_j, L_i, L_j; Jacobian (14 x nargs), row-major].
    """

    nargs: int
    nconst: int
    rows: int
    fn: Callable[..., list]


@cache
def _family(name: str) -> _Family:
    d = derive_friction(name)
    c = d.constraint
    args = [*s.q("i"), *s.q("j"), *s.qd("i"), *s.qd("j"), *c.constants, *c.lam, ARM_INV]
    values = [d.speed, d.normal, *d.generalized["i"], *d.generalized["j"], *d.loads["i"], *d.loads["j"]]
    jac = sp.Matrix(values).jacobian(sp.Matrix(args))
    fn = sp.lambdify(args, values + list(jac), modules=[np], cse=True)
    return _Family(len(args), len(c.constants), len(c.lam), fn)


@dataclass(frozen=True)
class _Joint:
    name: str
    family: str
    row: int  # its first multiplier row
    bodies: tuple[int, int]  # i, j (nb: ground)
    group: int  # its constraint group, and its member there
    member: int
    keys: Array  # (4,) coulomb, viscous, v_smooth, arm_inv
    keys_p: Array  # (4, np) their derivatives by the chosen parameters


def _joints(layout: Layout, values: Mapping[sp.Symbol, float], names: Sequence[str]) -> tuple[_Joint, ...]:
    mech = layout.mechanism
    params = mech.parameters
    index = {**mech.body_index(), "ground": layout.nb}
    member = {n: (g, m) for g, grp in enumerate(layout.constraint_groups) for m, n in enumerate(grp.names)}
    out = []
    for c in mech.constraints:
        if not has_friction(c):
            continue
        fr = c.friction
        exprs = (coulomb_arm(c.type, fr), fr["viscous"], fr["v_smooth"], inverse_arm(fr))
        full = [expand_derived(e, params) for e in exprs]
        keys = np.array([to_float(e, values) for e in exprs])
        keys_p = np.array([[to_float(sp.diff(e, parameter_symbol(n)), values) for n in names] for e in full])
        g, m = member[c.name]
        out.append(_Joint(c.name, c.type, layout.row_of[c.name][0], (index[c.bodies["i"]], index[c.bodies["j"]]),
                          g, m, keys, keys_p.reshape(4, len(names))))
    return tuple(out)


class FrictionSensitivity:
    """The friction terms of one mechanism's sensitivities (see the module docstring).

    Args:
        layout, values: the mechanism laid out, every parameter's value.
        names: the base parameters, in column order.
    """

    def __init__(self, layout: Layout, values: Mapping[sp.Symbol, float], names: Sequence[str]) -> None:
        self.layout = layout
        self.joints = _joints(layout, values, names)
        mech = layout.mechanism
        self.starts, _ = mech.reaction_starts({c.name for c in mech.constraints})

    def solve(self, qx: Array, qdx: Array, lam: Array, qpx: Array, qdpx: Array,
              const: Callable[[int, int], tuple[Array, Array]], rest: Array,
              solve_t: Callable[[Array], Array]) -> tuple[Array, Array, Array, Array]:
        """lam_p with friction, and what the reactions and friction columns need.

        Args:
            qx, qdx: extended (ng + 3, K) coordinates and rates; lam: (nc, K) with friction.
            qpx, qdpx: extended (ng + 3, K, np) q_p, qd_p.
            const: (group, member) -> the member's constants (nconst,) and their derivatives (nconst, np).
            rest: (ng, K, np) the derivative of the equations of motion but Phi_q^T lam_p (without friction).
            solve_t: (ng, K, m) -> (nc, K, m), Phi_q^T x = rhs at each instant.

        Returns:
            lam_p (nc, K, np); per joint f (nf, K), y = f_p (nf, K, np), and
            the loads' terms of the reactions' derivatives `L_p f` (nf, 6, K, np)
            and unit loads L (nf, 6, K); speed (nf, K) and speed_p (nf, K, np).
        """
        ng, count, nparams = rest.shape
        nf, nc = len(self.joints), lam.shape[0]
        g_unit = np.zeros((ng + 3, count, nf))
        rhs = -rest.copy()
        rhs_x = np.zeros((ng + 3, count, nparams))
        f = np.zeros((nf, count))
        f_p = np.zeros((nf, count, nparams))  # F_p: all but through lam
        f_lam = []  # per joint (rows, K): dF/dlam over its rows
        self._loads, self._loads_p = np.zeros((nf, 6, count)), np.zeros((nf, 6, count, nparams))
        self._speed, self._speed_p = np.zeros((nf, count)), np.zeros((nf, count, nparams))
        for k, jt in enumerate(self.joints):
            fam = _family(jt.family)
            rows = fam.rows
            i, j = jt.bodies
            ci, cp = const(jt.group, jt.member)
            local = [*qx[3 * i:3 * i + 3], *qx[3 * j:3 * j + 3], *qdx[3 * i:3 * i + 3], *qdx[3 * j:3 * j + 3],
                     *[np.full(count, v) for v in ci], *lam[jt.row:jt.row + rows], np.full(count, jt.keys[3])]
            out = [np.broadcast_to(np.asarray(v, dtype=float), (count,)) for v in fam.fn(*local)]
            vals = np.array(out[:14])  # (14, K)
            jac = np.array(out[14:]).reshape(14, fam.nargs, count)
            # the direction of every local argument but the multipliers: (nargs, K, np)
            dirs = np.zeros((fam.nargs, count, nparams))
            dirs[0:3], dirs[3:6] = qpx[3 * i:3 * i + 3], qpx[3 * j:3 * j + 3]
            dirs[6:9], dirs[9:12] = qdpx[3 * i:3 * i + 3], qdpx[3 * j:3 * j + 3]
            dirs[12:12 + fam.nconst] = cp[:, None, :]
            dirs[-1] = jt.keys_p[3][None, :]
            tan = np.einsum("eak,akp->ekp", jac, dirs)  # (14, K, np): every value's derivative but via lam
            speed, normal = vals[0], vals[1]
            coulomb, viscous, vs = jt.keys[:3]
            coulomb_p, viscous_p, vs_p = jt.keys_p[:3]
            if vs > 0:
                sign = np.tanh(speed / vs)
                sign_p = (1 - sign ** 2)[:, None] * (tan[0] / vs - speed[:, None] * vs_p[None, :] / vs ** 2)
            else:  # the exact sign: constant away from rest (at rest the solve refuses Coulomb friction)
                sign, sign_p = np.sign(speed), np.zeros((count, nparams))
            f[k] = -(coulomb * sign * normal + viscous * speed)
            f_p[k] = -(coulomb_p[None, :] * (sign * normal)[:, None] + coulomb * sign_p * normal[:, None]
                       + (coulomb * sign)[:, None] * tan[1] + viscous_p[None, :] * speed[:, None] + viscous * tan[0])
            # |F| = 0 has no derivative: none taken, as the solve
            f_lam.append(-(coulomb * sign)[None, :] * np.nan_to_num(jac[1, 12 + fam.nconst:12 + fam.nconst + rows]))
            for role, body, at in (("i", i, 2), ("j", j, 5)):
                g_unit[3 * body:3 * body + 3, :, k] += vals[at:at + 3]
                rhs_x[3 * body:3 * body + 3] += tan[at:at + 3] * f[k][None, :, None]
            self._loads[k], self._loads_p[k] = vals[8:14], tan[8:14]
            self._speed[k], self._speed_p[k] = speed, tan[0]
        rhs = rhs + rhs_x[:ng]
        a = solve_t(rhs)  # (nc, K, np)
        x = solve_t(np.ascontiguousarray(g_unit[:ng]))  # (nc, K, nf)
        # (I - F_lam X) y = F_p + F_lam A, instant by instant
        jmat = np.repeat(np.eye(nf)[None], count, axis=0)  # (K, nf, nf)
        right = f_p.transpose(1, 0, 2).copy()  # (K, nf, np)
        for k, jt in enumerate(self.joints):
            rows = f_lam[k].shape[0]
            sl = slice(jt.row, jt.row + rows)
            jmat[:, k, :] -= np.einsum("rk,rkm->km", f_lam[k], x[sl])
            right[:, k, :] += np.einsum("rk,rkp->kp", f_lam[k], a[sl])
        y = np.linalg.solve(jmat, right).transpose(1, 0, 2)  # (nf, K, np)
        lam_p = a + np.einsum("ckm,mkp->ckp", x, y)
        self._f, self._y = f, y
        return lam_p, f, y, self._loads

    def reactions(self, r_p: Array, slots: Mapping[str, int]) -> None:
        """Add each joint's `L_p f + L y` to the reaction derivatives r_p (rows, K, np)
        at the joint's slot (name -> first row; joints not there are not output)."""
        for k, jt in enumerate(self.joints):
            if jt.name not in slots:
                continue
            at = slots[jt.name]
            r_p[at:at + 6] += (self._loads_p[k] * self._f[k][None, :, None]
                               + self._loads[k][:, :, None] * self._y[k][None, :, :])

    def columns(self) -> Array:
        """The friction columns' derivatives (2 nf, K, np): per joint d(friction), d(friction_power)."""
        nf = len(self.joints)
        out = np.empty((2 * nf, *self._y.shape[1:]))
        out[0::2] = self._y
        out[1::2] = self._y * self._speed[:, :, None] + self._f[:, :, None] * self._speed_p
        return out
