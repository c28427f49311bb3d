"""A high-precision instant solver for the sensitivity tests: the whole
mechanism's Phi(q, t, p), nu, gamma, Q^A, M and reactions as sympy
expressions of the base parameters p, lambdified with mpmath and solved at
40 digits (Newton from the double-precision solution, then the rates,
multipliers and reactions). Central differences of it with a step of 1e-12
are exact to ~1e-20: a truth far below the 1e-9 the sensitivities are held to.

It uses the families' derivations (Phi, nu, gamma, reactions on generic
symbols) but none of the sensitivity code: no parameter derivative is taken
symbolically here.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import mpmath
import sympy as sp

from symid.model.friction import coulomb_arm, has_friction, inverse_arm
from symid.model.mechanism import GROUND, T, Mechanism, parameter_symbol
from symid.model.params import base_names
from symid.symbolic import symbols as s
from symid.symbolic.assemble import assemble
from symid.symbolic.friction import ARM_INV, derive_friction

DIGITS = 40


class _LU:
    """Gaussian elimination with partial pivoting of a square matrix of mpf,
    factored once and solved for any number of right-hand sides: the same
    40-digit solution as mpmath.lu_solve, on plain lists (mpmath's matrix
    indexing made its LU 20 times slower than its arithmetic)."""

    @mpmath.extraprec(10)  # as mpmath.lu_solve works
    def __init__(self, rows) -> None:  # type: ignore[no-untyped-def]
        a = [[mpmath.mpf(e) for e in r] for r in rows]
        n = len(a)
        perm = list(range(n))
        for k in range(n):
            p = max(range(k, n), key=lambda i: abs(a[i][k]))
            if not a[p][k]:
                raise ZeroDivisionError("matrix is numerically singular")
            if p != k:
                a[k], a[p] = a[p], a[k]
                perm[k], perm[p] = perm[p], perm[k]
            pivot, row_k = a[k][k], a[k]
            for i in range(k + 1, n):
                row_i = a[i]
                f = row_i[k] / pivot
                row_i[k] = f
                if f:
                    for j in range(k + 1, n):
                        row_i[j] -= f * row_k[j]
        self.a, self.perm, self.n = a, perm, n

    @mpmath.extraprec(10)
    def solve(self, b) -> mpmath.matrix:  # type: ignore[no-untyped-def]
        a, n = self.a, self.n
        x = [mpmath.mpf(b[i]) for i in self.perm]
        for i in range(n):
            row = a[i]
            x[i] -= mpmath.fsum(row[j] * x[j] for j in range(i)) if i else 0
        for i in reversed(range(n)):
            row = a[i]
            x[i] = (x[i] - mpmath.fsum(row[j] * x[j] for j in range(i + 1, n))) / row[i]
        return mpmath.matrix(x)


def _transposed(rows: list[list]) -> list[list]:
    return [list(c) for c in zip(*rows)]


def _base_only(expr: sp.Expr, parameters: Mapping[str, sp.Expr]) -> sp.Expr:
    out = sp.sympify(expr)
    for _ in range(len(parameters) + 1):
        out = out.xreplace({parameter_symbol(n): sp.sympify(e) for n, e in parameters.items()
                            if sp.sympify(e).free_symbols})
    return out


class Instant:
    """The mechanism's instant at 40 digits, as a function of the base parameters.

    `solve(t, p, q_guess)` -> dict of mpmath matrices q, qd, qdd, lam, reactions
    (reactions: every constraint, file order, Fx Fy T per role).
    """

    def __init__(self, mech: Mechanism) -> None:
        layout = assemble(mech)
        self.names = base_names(mech.parameters)
        self.p = [parameter_symbol(n) for n in self.names]
        nb, ng = layout.nb, layout.ng
        q = sp.symbols(f"q0:{ng}", real=True)
        qd = sp.symbols(f"qd0:{ng}", real=True)
        lam = sp.symbols(f"lam0:{layout.nc}", real=True)
        self.ng, self.nc = ng, layout.nc
        base = lambda e: _base_only(e, mech.parameters)  # noqa: E731

        def coords(role: str, body: int, rates: bool = False) -> dict:
            src = s.qd(role) if rates else s.q(role)
            dst = (qd if rates else q)[3 * body:3 * body + 3] if body < nb else (0, 0, 0)
            return dict(zip(src, dst))

        phi, nu, gamma = [sp.S(0)] * layout.nc, [sp.S(0)] * layout.nc, [sp.S(0)] * layout.nc
        reactions: dict[str, list[sp.Expr]] = {}
        for g in layout.constraint_groups:
            d = g.derived
            for m, name in enumerate(g.names):
                sub = {}
                for role in d.roles:
                    sub.update(coords(role, g.bodies[role][m]))
                    sub.update(coords(role, g.bodies[role][m], rates=True))
                sub.update({c: base(v) for c, v in zip(d.constants, g.constants[m])})
                if d.functions:
                    f = base(g.functions[m][0])
                    sub.update(dict(zip(d.functions, (f, sp.diff(f, T), sp.diff(f, T, 2)))))
                row = g.rows[m]
                k = len(d.lam)
                sub.update(dict(zip(d.lam, lam[row:row + k])))
                for r in range(k):
                    phi[row + r] = d.phi[r].xreplace(sub)
                    nu[row + r] = d.nu[r].xreplace(sub)
                    gamma[row + r] = d.gamma[r].xreplace(sub)
                reactions[name] = [e.xreplace(sub) for role in d.roles for e in d.reactions[role]]
        applied = [sp.S(0)] * ng
        for k, b in enumerate(mech.bodies):
            applied[3 * k] += base(b.mass * mech.gravity[0])
            applied[3 * k + 1] += base(b.mass * mech.gravity[1])
        for g in layout.force_groups:
            d = g.derived
            for m in range(g.size):
                sub = {}
                for role in d.roles:
                    sub.update(coords(role, g.bodies[role][m]))
                    sub.update(coords(role, g.bodies[role][m], rates=True))
                sub.update({c: base(v) for c, v in zip(d.constants, g.constants[m])})
                sub.update({f: base(v) for f, v in zip(d.functions, g.functions[m])})
                for role in d.roles:
                    body = g.bodies[role][m]
                    if body < nb:
                        for c in range(3):
                            applied[3 * body + c] += d.generalized[role][c].xreplace(sub)
        mass = [base(e) for b in mech.bodies for e in (b.mass, b.mass, b.inertia)]
        # joint friction (contract v1.1), inverse dynamics only: per joint its
        # speed, N(lam), coefficients and the unit friction's generalized
        # forces and loads, from the family's derivation (no derivative by p)
        member = {n: (g, m) for g in layout.constraint_groups for m, n in enumerate(g.names)}
        friction: list[sp.Expr] = []
        self.nf = 0
        for c in mech.constraints if mech.analysis.kind == "inverse_dynamics" else ():
            if not has_friction(c):
                continue
            g, m = member[c.name]
            d = derive_friction(c.type)
            sub = {}
            for role in d.constraint.roles:
                sub.update(coords(role, g.bodies[role][m]))
                sub.update(coords(role, g.bodies[role][m], rates=True))
            sub.update({k: base(v) for k, v in zip(d.constraint.constants, g.constants[m])})
            row = g.rows[m]
            sub.update(dict(zip(d.constraint.lam, lam[row:row + len(d.constraint.lam)])))
            sub[ARM_INV] = base(inverse_arm(c.friction))
            gen = [sp.S(0)] * ng
            for role in ("i", "j"):
                body = g.bodies[role][m]
                if body < nb:
                    for k in range(3):
                        gen[3 * body + k] += d.generalized[role][k].xreplace(sub)
            loads = [e.xreplace(sub) for role in ("i", "j") for e in d.loads[role]]
            friction += [d.speed.xreplace(sub), d.normal.xreplace(sub), base(coulomb_arm(c.type, c.friction)),
                         base(c.friction["viscous"]), base(c.friction["v_smooth"]), *gen, *loads]
            self.nf += 1
            self.friction_names = getattr(self, "friction_names", []) + [c.name]
        self.fw = 5 + ng + 6
        phi_m = sp.Matrix(phi)
        jac = phi_m.jacobian(sp.Matrix(q))
        args = [q, qd, lam, T, self.p]
        # cse: the rows share subtrees (a body's sine and cosine, a joint's arm); evaluated
        # once each, with the same arithmetic at 40 digits otherwise
        fn = lambda exprs: sp.lambdify(args, exprs, modules="mpmath", cse=True)  # noqa: E731
        self._phi, self._jac, self._nu, self._gamma = fn(list(phi)), fn(jac.tolist()), fn(nu), fn(gamma)
        self._applied, self._mass = fn(applied), fn(mass)
        self._reactions = fn([e for c in mech.constraints for e in reactions[c.name]])
        self._friction = fn(friction) if friction else None
        # only each joint's normal force depends on the multipliers: the fixed-point
        # iteration evaluates those alone (the rest once per instant)
        normals = friction[1::self.fw]
        assert not any(set(lam) & e.free_symbols for k, e in enumerate(friction) if k % self.fw != 1)
        self._normals = fn(normals) if friction else None
        self._starts = {}
        at = 0
        for c in mech.constraints:
            self._starts[c.name] = at
            at += len(reactions[c.name])

    def solve(self, t: float, p: Sequence, q_guess: Sequence[float]) -> dict[str, mpmath.matrix]:
        with mpmath.workdps(DIGITS):
            t = mpmath.mpf(t)
            p = [mpmath.mpf(v) for v in p]
            q = [mpmath.mpf(v) for v in q_guess]
            zeros_v, zeros_l = [0] * self.ng, [0] * self.nc
            for _ in range(60):
                phi = self._phi(q, zeros_v, zeros_l, t, p)
                dq = _LU(self._jac(q, zeros_v, zeros_l, t, p)).solve([-e for e in phi])
                q = [a + b for a, b in zip(q, dq)]
                if mpmath.norm(dq, mpmath.inf) < mpmath.mpf(10) ** (-DIGITS + 5):
                    break
            jac = self._jac(q, zeros_v, zeros_l, t, p)
            lu, lu_t = _LU(jac), _LU(_transposed(jac))  # Phi_q for the rates, Phi_q^T for the multipliers
            qd = lu.solve(self._nu(q, zeros_v, zeros_l, t, p))
            qdl = list(qd)
            qdd = lu.solve(self._gamma(q, qdl, zeros_l, t, p))
            rhs = mpmath.matrix(self._applied(q, qdl, zeros_l, t, p))
            mass = self._mass(q, qdl, zeros_l, t, p)
            for k in range(self.ng):
                rhs[k] -= mass[k] * qdd[k]
            lam = lu_t.solve(rhs)
            out = {"q": mpmath.matrix(q), "qd": qd, "qdd": qdd}
            if self._friction is None:
                out["lam"] = lam
                out["reactions"] = mpmath.matrix(self._reactions(q, qdl, list(lam), t, p))
                return out
            # with friction: Phi_q^T lam = rhs + G f(lam), by fixed-point
            # iteration (a contraction for these friction coefficients) to 40 digits
            fw, ng = self.fw, self.ng
            v = self._friction(q, qdl, list(lam), t, p)  # all but the normal forces: fixed at this instant
            for _ in range(400):
                normals = self._normals(q, qdl, list(lam), t, p)
                f = []
                total = mpmath.matrix(rhs)
                for k in range(self.nf):
                    speed, c, visc, vs = v[k * fw], *v[k * fw + 2:k * fw + 5]
                    normal = normals[k]
                    s = mpmath.tanh(speed / vs) if vs > 0 else mpmath.sign(speed)
                    f.append(-(c * s * normal + visc * speed))
                    for r in range(ng):
                        total[r] += v[k * fw + 5 + r] * f[k]
                new = lu_t.solve(total)
                moved = mpmath.norm(new - lam, mpmath.inf)
                lam = new
                if moved < mpmath.mpf(10) ** (-DIGITS + 5):
                    break
            else:
                raise AssertionError("the 40-digit friction iteration did not converge")
            reactions = mpmath.matrix(self._reactions(q, qdl, list(lam), t, p))
            columns = []
            for k, name in enumerate(self.friction_names):
                speed = v[k * fw]
                loads = v[k * fw + 5 + ng:k * fw + fw]
                for r in range(6):
                    reactions[self._starts[name] + r] += loads[r] * f[k]
                columns += [f[k], f[k] * speed]
            out.update(lam=lam, reactions=reactions, friction=mpmath.matrix(columns))
            return out
