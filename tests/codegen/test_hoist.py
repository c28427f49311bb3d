"""`symid.codegen.hoist`: the pieces it takes out read parameters only, and
putting them back gives the expressions it was given (truth: the input itself,
and the parameter-only test written here on free_symbols)."""

from __future__ import annotations

import sympy as sp

from symid.codegen.hoist import hoist

P = [sp.Symbol(f"p[{k}]", real=True) for k in range(3)]
Q = [sp.Symbol(f"q[{k}]", real=True) for k in range(2)]
T = sp.Symbol("t", real=True)


def _params_only(e: sp.Expr) -> bool:
    return bool(e.free_symbols) and all(x.name.startswith("p[") for x in e.free_symbols)


def test_hoisted_pieces_read_parameters_only_and_put_back_give_the_input():
    exprs = [[P[0] * P[1] ** 2 / 12 * sp.cos(Q[0]) + sp.sin(P[2] * T),
              4 * sp.pi ** 2 * P[2] ** 2 * Q[1] + P[0] * P[1] ** 2 / 12,
              sp.sqrt(P[0] ** 2 + P[1] ** 2) + Q[0] * Q[1] + P[0] * P[1] * Q[0]],
             [sp.Piecewise((P[0] * P[1], Q[0] > 0), (P[1], True)), sp.sin(P[0] + P[1]) * sp.cos(Q[1] + P[2])]]
    out, pieces = hoist(exprs, 3)
    assert pieces and all(_params_only(v) for v in pieces)
    back = {sp.Symbol(f"p[{3 + j}]", real=True): v for j, v in enumerate(pieces)}
    assert [[e.xreplace(back) for e in row] for row in out] == exprs
    # a piece shared by two expressions is one value, and nothing reading q or t stays hoisted
    assert len(set(pieces)) == len(pieces)
    assert all(not (v.free_symbols & {*Q, T}) for v in pieces)
    # what is left reads a hoisted symbol where the parameter-only piece was
    assert not any(_params_only(e) and not e.is_Atom for row in out for e in row)
