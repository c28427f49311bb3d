"""LU factors of K square matrices at once, in the generated module's fixed
pivot order (its PIVOT_ROWS, PIVOT_COLS), for the vectorized NumPy sweep.

The generated NumPy module factors Phi_q in a sparse order fixed at
generation time, and hands an instant over where a pivot fails its
threshold test. Here the same elimination runs one structural entry at a
time for all K variants (each entry's K values contiguous): the factors are
the module's bit for bit, the solves the same up to the order of a few
sums (measured on the bundled examples: identical, or 1 ulp apart), in a
few dozen array operations per factorization where `np.linalg.solve` pays
LAPACK's call and pivot search per matrix. The pivots also give the
module's pivot-spread screen.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from symid.backends import Array


class Plan:
    """The elimination's structure, fixed once per module: the permuted
    positions of Phi_q's stored entries, and per step the rows below (L's
    entries) and the columns right (U's) that are structurally nonzero,
    fill-in included. Only those are touched: as the module's straight-line
    code, one operation per structural entry, here on K values at once.

    Args:
        jac_rows, jac_cols: the stored entries of Phi_q (the module's
            PHI_Q_ROWS, PHI_Q_COLS); rows, cols: the pivot order (step k
            pivots at Phi_q[rows[k], cols[k]]).
    """

    def __init__(self, jac_rows: Sequence[int], jac_cols: Sequence[int], rows: Sequence[int],
                 cols: Sequence[int]) -> None:
        self.jac_rows = np.asarray(jac_rows, dtype=np.intp)
        self.jac_cols = np.asarray(jac_cols, dtype=np.intp)
        self.rows = np.asarray(rows, dtype=np.intp)
        self.cols = np.asarray(cols, dtype=np.intp)
        n = self.n = len(self.rows)
        at_row = np.empty(n, dtype=np.intp)
        at_row[self.rows] = np.arange(n)
        at_col = np.empty(n, dtype=np.intp)
        at_col[self.cols] = np.arange(n)
        self.at = (at_row[np.asarray(jac_rows, dtype=np.intp)], at_col[np.asarray(jac_cols, dtype=np.intp)])
        pattern = np.zeros((n, n), dtype=bool)
        pattern[self.at] = True
        self.below: list[list[int]] = []
        self.right: list[list[int]] = []
        for j in range(n):
            self.below.append([i for i in range(j + 1, n) if pattern[i, j]])
            self.right.append([c for c in range(j + 1, n) if pattern[j, c]])
            for i in self.below[j]:
                pattern[i, self.right[j]] = True  # fill-in


class Factors:
    """B = Phi_q[rows][:, cols] = L U for K matrices in a `Plan`'s order.

    Stored (N, N, K): each entry's K values are contiguous.

    Args:
        plan: the structure; values: (NNZ, K) the stored entries of each
            Phi_q; threshold: a pivot must be at least this times every
            entry below it in its column (the module's test).

    Attributes:
        ok: (K,) every pivot nonzero and passing the threshold test (where
            not, the module takes its dense fallback and hands the instant over).
    """

    def __init__(self, plan: Plan, values: Array, threshold: float) -> None:
        self.plan = plan
        self.values = values
        n, k = plan.n, values.shape[1]
        b = np.zeros((n, n, k))
        b[plan.at] = values
        ok = np.ones(k, dtype=bool)
        for j in range(n):
            u = np.abs(b[j, j])
            ok &= u > 0
            pivot = b[j, j]
            for i in plan.below[j]:
                ok &= u >= threshold * np.abs(b[i, j])
                b[i, j] /= pivot
                for c in plan.right[j]:
                    b[i, c] -= b[i, j] * b[j, c]
        self.lu, self.ok = b, ok

    def pivots(self) -> Array:
        """|u_k| of each step, (N, K)."""
        return np.abs(np.diagonal(self.lu, axis1=0, axis2=1).T)

    def solve(self, rhs: Array) -> Array:
        """x (N, K) with Phi_q x = rhs (N, K), per variant."""
        b, plan = self.lu, self.plan
        y = np.array(np.broadcast_to(rhs, (plan.n, b.shape[2]))[plan.rows])
        for j in range(plan.n):  # L y = P rhs
            for i in plan.below[j]:
                y[i] -= b[i, j] * y[j]
        for j in range(plan.n - 1, -1, -1):  # U z = y
            for c in plan.right[j]:
                y[j] -= b[j, c] * y[c]
            y[j] /= b[j, j]
        x = np.empty_like(y)
        x[plan.cols] = y
        return x

    def solve_t(self, rhs: Array) -> Array:
        """lambda (N, K) with Phi_q^T lambda = rhs (N, K), per variant."""
        b, plan = self.lu, self.plan
        w = np.array(np.broadcast_to(rhs, (plan.n, b.shape[2]))[plan.cols])
        for j in range(plan.n):  # U^T w = Q^T rhs
            w[j] /= b[j, j]
            for c in plan.right[j]:
                w[c] -= b[j, c] * w[j]
        for j in range(plan.n - 1, -1, -1):  # L^T v = w
            for i in plan.below[j]:
                w[j] -= b[i, j] * w[i]
        out = np.empty_like(w)
        out[plan.rows] = w
        return out

    def refine_t(self, rhs: Array, lam: Array, mixed: Array) -> Array:
        """lam (N, K) after one step of iterative refinement of Phi_q^T lam =
        rhs in the variants where `mixed` (K,) is set (the module's `_refine_t`:
        a light body's multipliers would carry a heavy one's rounding); the
        others as they are."""
        if not mixed.any():
            return lam
        plan = self.plan
        r = np.array(np.broadcast_to(rhs, lam.shape))
        np.subtract.at(r, plan.jac_cols, self.values * lam[plan.jac_rows])
        return np.where(mixed, lam + self.solve_t(r), lam)
