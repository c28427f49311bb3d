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

from symid.model.mechanism import GROUND, T, Mechanism, parameter_symbol
from symid.model.params import base_names
from symid.symbolic import symbols as s
from symid.symbolic.assemble import assemble

DIGITS = 40


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
        phi_m = sp.Matrix(phi)
        jac = phi_m.jacobian(sp.Matrix(q))
        args = [q, qd, lam, T, self.p]
        fn = lambda exprs: sp.lambdify(args, exprs, modules="mpmath")  # noqa: E731
        self._phi, self._jac, self._nu, self._gamma = fn(list(phi)), fn(jac.tolist()), fn(nu), fn(gamma)
        self._applied, self._mass = fn(applied), fn(mass)
        self._reactions = fn([e for c in mech.constraints for e in reactions[c.name]])

    def solve(self, t: float, p: Sequence, q_guess: Sequence[float]) -> dict[str, mpmath.matrix]:
        with mpmath.workdps(DIGITS):
            t = mpmath.mpf(t)
            p = [mpmath.mpf(v) for v in p]
            q = [mpmath.mpf(v) for v in q_guess]
            zeros_v, zeros_l = [0] * self.ng, [0] * self.nc
            for _ in range(60):
                phi = mpmath.matrix(self._phi(q, zeros_v, zeros_l, t, p))
                dq = mpmath.lu_solve(mpmath.matrix(self._jac(q, zeros_v, zeros_l, t, p)), -phi)
                q = [a + b for a, b in zip(q, dq)]
                if mpmath.norm(dq, mpmath.inf) < mpmath.mpf(10) ** (-DIGITS + 5):
                    break
            jac = mpmath.matrix(self._jac(q, zeros_v, zeros_l, t, p))
            qd = mpmath.lu_solve(jac, mpmath.matrix(self._nu(q, zeros_v, zeros_l, t, p)))
            qdl = list(qd)
            qdd = mpmath.lu_solve(jac, mpmath.matrix(self._gamma(q, qdl, zeros_l, t, p)))
            rhs = mpmath.matrix(self._applied(q, qdl, zeros_l, t, p))
            mass = self._mass(q, qdl, zeros_l, t, p)
            for k in range(self.ng):
                rhs[k] -= mass[k] * qdd[k]
            lam = mpmath.lu_solve(jac.T, rhs)
            reactions = mpmath.matrix(self._reactions(q, qdl, list(lam), t, p))
            return {"q": mpmath.matrix(q), "qd": qd, "qdd": qdd, "lam": lam, "reactions": reactions}
