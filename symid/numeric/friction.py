"""Joint friction solved with the multipliers at each instant (contract v1.1).

With friction the equations of motion `Phi_q^T lambda = b + G f(lambda)`
(b = Q^A - M qddot, G the generalized forces of a unit friction per joint,
f the frictions) are no longer linear in lambda. Since
`lambda = lambda_0 + X f` with `lambda_0` the frictionless multipliers and
`X = (Phi_q^T)^-1 G` (one solve per friction joint with the factorization
already made), Newton runs on the nf frictions alone: the exact Newton on
lambda, its Jacobian `Phi_q^T - G (df/dlambda)^T` inverted by the
Sherman-Morrison-Woodbury identity, so no new factorization is needed.
The sign s(speed) depends on the speeds only, so within an instant only
N(lambda) moves.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Callable, Mapping

import numpy as np
import sympy as sp

from symid.errors import AnalysisError
from symid.model.friction import coulomb_arm, has_friction, inverse_arm
from symid.model.mechanism import parameter_symbol
from symid.model.params import is_derived, to_float
from symid.numeric.evaluator import Array, Evaluator
from symid.numeric.stability import Factor
from symid.symbolic import symbols as s
from symid.symbolic.assemble import Layout, reaction_columns
from symid.symbolic.friction import ARM_INV, DerivedFriction, derive_friction

MAX_ITERATIONS = 20
# a joint is at rest when |speed| is within this of the largest |qdot| (or of 1)
REST = 1e-12


@cache
def _kernel(name: str) -> tuple[DerivedFriction, Callable[..., list]]:
    """(derivation, numeric kernel) of a family: args q_i, q_j, qd_i, qd_j,
    constants, multipliers, arm_inv -> [speed, N, dN/dlambda..., G_i, G_j, L_i, L_j]."""
    d = derive_friction(name)
    c = d.constraint
    args = [*s.q("i"), *s.q("j"), *s.qd("i"), *s.qd("j"), *c.constants, *c.lam, ARM_INV]
    exprs = [d.speed, d.normal, *d.d_normal, *d.generalized["i"], *d.generalized["j"], *d.loads["i"],
             *d.loads["j"]]
    return d, sp.lambdify(args, exprs, modules=[np], cse=True)


@dataclass(frozen=True)
class Joint:
    """One joint with friction: where it sits and its friction's numbers."""

    name: str
    family: str
    rows: tuple[int, int]
    bodies: tuple[int, int]  # body indices of i, j (nb: ground)
    constants: tuple[float, ...]
    coulomb: float  # mu * radius (pin) or mu (slide)
    viscous: float
    v_smooth: float
    arm_inv: float


@dataclass
class Solved:
    """The friction of one instant: lambda with friction, and per joint the
    friction f (torque or force on j), its speed and the Newton iterations."""

    lam: Array
    friction: Array
    speed: Array
    iterations: int

    @property
    def power(self) -> Array:
        return self.friction * self.speed

    def columns(self) -> Array:
        """The table's friction columns: per joint its friction and its power."""
        return np.column_stack([self.friction, self.power]).reshape(-1)


def joints_of(layout: Layout, values: Mapping[sp.Symbol, float]) -> tuple[Joint, ...]:
    """The layout's joints with friction, in file order, with numeric values."""
    nb = layout.nb
    index = {**layout.mechanism.body_index(), "ground": nb}
    member = {name: (g, k) for g in layout.constraint_groups for k, name in enumerate(g.names)}
    out = []
    for c in layout.mechanism.constraints:
        if not has_friction(c):
            continue
        group, k = member[c.name]
        fr = c.friction
        out.append(Joint(
            name=c.name, family=c.type, rows=layout.row_of[c.name],
            bodies=(index[c.bodies["i"]], index[c.bodies["j"]]),
            constants=tuple(to_float(e, values) for e in group.constants[k]),
            coulomb=to_float(coulomb_arm(c.type, fr), values), viscous=to_float(fr["viscous"], values),
            v_smooth=to_float(fr["v_smooth"], values), arm_inv=to_float(inverse_arm(fr), values)))
    return tuple(out)


class FrictionModel:
    """The frictions of one mechanism with numeric parameter values.

    Args:
        layout: the mechanism's layout; values: parameter symbol -> value.
    """

    def __init__(self, layout: Layout, values: Mapping[sp.Symbol, float]) -> None:
        self.layout = layout
        self.joints = joints_of(layout, values)
        self.names = tuple(j.name for j in self.joints)

    def with_params(self, params: Mapping[str, float]) -> FrictionModel:
        """The same joints with other parameter values (name -> value, every
        parameter, derived ones included, as the evaluators' `with_params`
        take them; derived ones are recomputed): mu, radius, viscous, arm, v_smooth and the joints'
        geometry follow the variant."""
        values: dict[sp.Symbol, float] = {}
        for name, expr in self.layout.mechanism.parameters.items():  # dependency order
            sym = parameter_symbol(name)
            given = name in params and not is_derived(expr)  # a derived one follows its definition
            values[sym] = float(params[name]) if given else to_float(expr, values, name)
        return FrictionModel(self.layout, values)

    def _evaluate(self, joint: Joint, qx: Array, qdx: Array, lam: Array) -> list[float]:
        i, j = joint.bodies
        start, rows = joint.rows
        _, kernel = _kernel(joint.family)
        return [float(v) for v in kernel(*qx[3 * i:3 * i + 3], *qx[3 * j:3 * j + 3], *qdx[3 * i:3 * i + 3],
                                         *qdx[3 * j:3 * j + 3], *joint.constants, *lam[start:start + rows],
                                         joint.arm_inv)]

    def _unit_forces(self, joint: Joint, values: list[float], ng: int) -> Array:
        """G of one joint: the generalized force (ng,) of a unit friction."""
        rows = joint.rows[1]
        g = np.zeros(ng + 3)
        i, j = joint.bodies
        g[3 * i:3 * i + 3] += values[2 + rows:5 + rows]
        g[3 * j:3 * j + 3] += values[5 + rows:8 + rows]
        return g[:ng]

    def solve(self, q: Array, qd: Array, lam0: Array, factor: Factor, t: float, tol: float) -> Solved:
        """The multipliers with friction at (q, qd), from the frictionless lam0.

        Raises:
            AnalysisError: a joint with exact-sign Coulomb friction at rest (its
                friction is undetermined), or no convergence.
        """
        ng, nc, nf = q.size, lam0.size, len(self.joints)
        qx, qdx = np.concatenate([q, np.zeros(3)]), np.concatenate([qd, np.zeros(3)])
        first = [self._evaluate(jt, qx, qdx, lam0) for jt in self.joints]
        speed = np.array([v[0] for v in first])
        rest = REST * max(1.0, float(np.abs(qd).max(initial=0.0)))
        sign = np.empty(nf)
        for k, jt in enumerate(self.joints):
            if jt.v_smooth > 0:
                sign[k] = np.tanh(speed[k] / jt.v_smooth)
            elif abs(speed[k]) <= rest:
                if jt.coulomb > 0:
                    raise AnalysisError(f"friction undetermined: joint {jt.name} is at rest with the exact "
                                        f"sign (v_smooth = 0); give v_smooth > 0", t)
                sign[k] = 0.0
            else:
                sign[k] = np.sign(speed[k])
        coulomb = np.array([jt.coulomb for jt in self.joints]) * sign
        viscous = np.array([jt.viscous for jt in self.joints]) * speed
        # X = (Phi_q^T)^-1 G: lambda = lam0 + X f
        x = np.column_stack([factor.solve_t(self._unit_forces(jt, v, ng)) for jt, v in zip(self.joints, first)])
        # from the frictionless solution, f = F(lam0): the friction its reactions give
        f = -(coulomb * np.array([v[1] for v in first]) + viscous)
        lam = lam0 + x @ f
        values = [self._evaluate(jt, qx, qdx, lam) for jt in self.joints]
        previous = float(np.abs(x @ f).max(initial=0.0))  # the move of that start
        for it in range(1, MAX_ITERATIONS + 1):
            normal = np.array([v[1] for v in values])
            residual = f + coulomb * normal + viscous  # f - F(lam0 + X f)
            d = np.zeros((nf, nc))  # dF/dlambda, F = -(c s N + viscous speed)
            for k, (jt, v) in enumerate(zip(self.joints, values)):
                start, rows = jt.rows
                d[k, start:start + rows] = -coulomb[k] * np.nan_to_num(np.array(v[2:2 + rows]))
            try:
                df = np.linalg.solve(np.eye(nf) - d @ x, -residual)
            except np.linalg.LinAlgError:
                raise AnalysisError(f"friction locks the mechanism: the equations with friction in "
                                    f"{', '.join(self.names)} have no unique solution", t) from None
            f = f + df
            lam = lam0 + x @ f
            step = float(np.abs(x @ df).max(initial=0.0))  # what the step moved lambda by
            if not np.isfinite(step):
                break
            # converged: the step just taken is within tol, or the steps contract
            # (rate theta < 1/2) so that all the steps still to come, at most
            # theta / (1 - theta) times this one, are
            lim = max(tol, 64 * np.finfo(float).eps) * max(1.0, float(np.abs(lam).max(initial=0.0)))
            theta = step / previous if previous > 0 else 1.0
            if step <= lim or (theta < 0.5 and theta / (1 - theta) * step <= lim):
                return Solved(lam=lam, friction=f, speed=speed, iterations=it)
            previous = step
            values = [self._evaluate(jt, qx, qdx, lam) for jt in self.joints]
        raise AnalysisError(f"friction did not converge in {MAX_ITERATIONS} Newton iterations "
                            f"(joints {', '.join(self.names)})", t)

    def reactions(self, ev: Evaluator, q: Array, solved: Solved, t: float, names: tuple[str, ...] | None) -> Array:
        """The reaction columns (as `Evaluator.reactions` for the constraints
        `names`, None: all) plus each joint's friction loads: the joint's whole action."""
        reactions = ev.reactions(q, solved.lam, t)
        start: dict[str, int] = {}
        for n, (c, _) in enumerate(reaction_columns(self.layout, names)):
            start.setdefault(c, n)
        out = reactions.copy()
        qx = np.concatenate([q, np.zeros(3)])
        zero = np.zeros(qx.size)
        for k, jt in enumerate(self.joints):
            if jt.name not in start:
                continue
            v = self._evaluate(jt, qx, zero, solved.lam)
            rows = jt.rows[1]
            loads = np.array(v[8 + rows:14 + rows]) * solved.friction[k]  # on i, then on j
            out[start[jt.name]:start[jt.name] + 6] += loads
        return out

