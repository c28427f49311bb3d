"""`symid.symbolic.differentiate`: the memoized derivatives are sympy's own.

Truth is sympy's `expr.diff(x)` and `Matrix.jacobian` (the code paths the
Differentiator replaces, run here unchanged), compared as trees (`==` and
`srepr`: the generated code prints the expression, so an equal value in another
form would change generated/), and the value against a central difference.
"""

from __future__ import annotations

import math

import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from symid import api
from symid.symbolic import symbols as s
from symid.symbolic.assemble import assemble
from symid.symbolic.derive import derive_constraint, reaction, total_derivative
from symid.symbolic.differentiate import Differentiator

X, Y, Z = sp.symbols("x y z", real=True)
P = sp.Symbol("p[0]", real=True)
LEAVES = [X, Y, Z, P, sp.Integer(2), sp.Rational(1, 3), sp.pi]
UNARY = [sp.sin, sp.cos, sp.sqrt, sp.exp, sp.Abs, sp.sign, sp.tan, lambda a: a ** 2, lambda a: 1 / a,
         lambda a: a ** sp.Rational(3, 2), lambda a: sp.Piecewise((a, X > 0), (a ** 2, True))]
BINARY = [sp.Add, sp.Mul, sp.atan2, lambda a, b: a ** b, lambda a, b: a - b, lambda a, b: a / b]


def _expr(depth: int) -> st.SearchStrategy[sp.Expr]:
    leaf = st.sampled_from(LEAVES)
    if depth == 0:
        return leaf
    sub = _expr(depth - 1)
    return st.one_of(leaf,
                     st.builds(lambda f, a: f(a), st.sampled_from(UNARY), sub),
                     st.builds(lambda f, a, b: f(a, b), st.sampled_from(BINARY), sub, sub),
                     st.builds(lambda a, b, c: sp.Mul(a, b, c), sub, sub, sub),
                     st.builds(lambda a, b, c: sp.Add(a, b, c), sub, sub, sub))


@settings(max_examples=60, deadline=None)
@given(_expr(3))
def test_derivative_is_sympys_tree(e):
    d = Differentiator()
    for x in (X, Y, P):
        mine = d.diff(e, x)
        assert mine == e.diff(x) and sp.srepr(mine) == sp.srepr(e.diff(x)), (e, x)


def test_shared_subtrees_are_differentiated_once_with_the_same_results():
    common = sp.sin(X * Y) * sp.sqrt(X ** 2 + Z ** 2)
    rows = [common + X, common * Y, sp.cos(common) - Z]
    d = Differentiator()
    assert d.jacobian(rows, [X, Y, Z, P]) == sp.Matrix(rows).jacobian([X, Y, Z, P])
    assert d.diff(rows[0], P) is sp.S.Zero  # not a free symbol: 0 with no walk
    assert d.diff(common, X) is d.diff(common, X)  # built once, then read


def test_value_equals_a_central_difference():
    # An independent check of the value (not sympy's diff): the slope of e along x.
    e = sp.atan2(sp.sin(X) * Y, X ** 2 + sp.sqrt(1 + Y ** 2)) * sp.exp(-X * Y)
    at = {X: 0.7, Y: -0.4}
    h = 1e-6  # O(h^2) truncation ~1e-12, rounding ~1e-16/h = 1e-10: 1e-8 covers both with margin
    fd = (float(e.subs({**at, X: 0.7 + h})) - float(e.subs({**at, X: 0.7 - h}))) / (2 * h)
    assert math.isclose(float(Differentiator().diff(e, X).subs(at)), fd, rel_tol=1e-8, abs_tol=1e-8)


def test_a_family_jacobians_equal_matrix_jacobian():
    # A real family's residuals: the revolute's Phi, its two total derivatives,
    # Phi_q^T lam and the reactions, by all local arguments.
    dc = derive_constraint("revolute")
    roles = dc.roles
    args = [x for r in roles for x in (*s.q(r), *s.qd(r), *s.qdd(r))] + list(dc.constants) + list(dc.lam)
    lam = sp.Matrix(dc.lam)
    vel = [total_derivative(e, roles) for e in dc.phi]
    rows = (list(dc.phi) + vel + [total_derivative(e, roles) for e in vel]
            + [e for r in roles for e in dc.jac[r].T * lam]
            + [e for r in roles for e in reaction(dc.jac[r], lam, dc.family.points[r], r)])
    mine = Differentiator().jacobian(rows, args)
    truth = sp.Matrix(rows).jacobian(sp.Matrix(args))
    assert mine == truth
    assert [sp.srepr(a) for a in mine] == [sp.srepr(b) for b in truth]


def test_gamma_sets_the_accelerations_to_zero_as_subs_does():
    # derive_constraint takes gamma from Phi's second total derivative with qdd -> 0 by
    # xreplace: the trees subs gives, on a revolute and on an expression row (a cam's shape)
    cam = [(g.family, g.variant) for g in assemble(api.load(api.example("disc_cam"))).constraint_groups
           if g.family == "expression"]
    assert cam
    for name, options in [("revolute", ())] + cam:
        dc = derive_constraint(name, options)
        by = Differentiator()
        second = [total_derivative(total_derivative(e, dc.roles, by), dc.roles, by) for e in dc.phi]
        zero = {a: 0 for r in dc.roles for a in s.qdd(r)}
        truth = [sp.expand(-e.subs(zero)) for e in second]  # derive's _tidy is expand
        assert list(dc.gamma) == truth and [sp.srepr(g) for g in dc.gamma] == [sp.srepr(t) for t in truth]
