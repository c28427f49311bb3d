"""The rank analysis of a large Phi_q without anything nc x ng: its rank,
the rows in its dependencies and its 2-norm condition number, as
`symid.numeric.redundancy.rank_of`'s SVD finds them, from sparse LU
factorizations of the augmented matrix [[-s I, a], [a^T, -s I]] of the
equilibrated a (nc x ng).

Why the augmented matrix. Solving it for [x; 0] applies
s (a a^T - s^2 I)^-1 to x: inverse iteration on a a^T, whose largest
eigenvalues are the left singular directions of a's smallest singular
values, without forming a a^T (which squares the condition number and would
lose the singular values near eps * s_max that decide the rank). With s half
the SVD's rank threshold, a null direction grows by 1 / s^2 an iteration and
one whose singular value is above the threshold by at most 1 / (3 s^2): a
few iterations of a block of k vectors span the left null space, and the
singular values of a^T restricted to it (a Rayleigh-Ritz step, exact on a
positive semi-definite matrix: no spurious small values) are a's own.

The rows in dependencies are those with a share of the projection on the
left null space above NULL_SHARE of the largest: the diagonal of that
projector, which does not depend on the basis, so the names are the dense
SVD's. Memory: the LU factors (for a chain, a few times the entries of a),
and blocks of k vectors of size nc.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symid.numeric.evaluator import Array
from symid.numeric.stability import EPS

# Block inverse iterations: each multiplies a direction above the rank
# threshold by at most 1/3 against a null one (typically by s^2 / s_min^2,
# under 1e-10), so the null space's span is exact to rounding after these;
# then on until the span moves by less than SPAN_TOL an entry (a smallest
# singular value counted as null converges against the next one only).
ITERATIONS, MAX_ITERATIONS, SPAN_TOL = 6, 500, 1e-13
SEED = 0  # the start block and ARPACK's start vector: the same figures every run


@dataclass(frozen=True)
class Analysis:
    """What the SVD of a (nc, ng) tells the rank analysis.

    Attributes:
        rank: singular values above max(nc, ng) eps s_max.
        share: size nc, each row's squared norm in the left null space's
            orthonormal basis (the projector's diagonal; the rows that the
            rank deems null, as `rank_of` takes them).
        cond: s_max / s_min at full column rank, else inf.
    """

    rank: int
    share: Array
    cond: float


def _augmented(a, shift: float):  # type: ignore[no-untyped-def]
    """SuperLU of [[-shift I, a], [a^T, -shift I]] (a: csc, nc x ng)."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    nc, ng = a.shape
    k = sparse.bmat([[-shift * sparse.identity(nc), a], [a.T, -shift * sparse.identity(ng)]], format="csc")
    return splu(k)


def _smax(a) -> float:  # type: ignore[no-untyped-def]
    from scipy.sparse.linalg import svds

    if a.nnz == 0:
        return 0.0
    v0 = np.random.default_rng(SEED).standard_normal(min(a.shape))
    return float(svds(a, k=1, return_singular_vectors=False, v0=v0)[0])


def analyse(a, singular: bool = False) -> Analysis:  # type: ignore[no-untyped-def]
    """The rank analysis of the equilibrated a (scipy sparse, nc x ng).

    singular: count at least one singular value as null even above the
    threshold, as `rank_of` does for a matrix its caller found singular.
    """
    a = a.tocsc()
    nc, ng = a.shape
    if min(nc, ng) < 3:  # too small for Lanczos: the dense SVD (a few entries)
        return dense(a.toarray(), singular)
    smax = _smax(a)
    least = max(nc - min(nc, ng) + (1 if singular else 0), 0)  # null directions at the least
    if not smax > 0 or not np.isfinite(smax):  # nothing but zeros: every row is null
        return Analysis(0, np.ones(nc), np.inf)
    threshold = max(nc, ng) * EPS * smax
    shift = threshold / 2
    for _ in range(4):
        try:
            lu = _augmented(a, shift)
            break
        except RuntimeError:  # an exactly zero pivot: the shift met a singular value
            shift *= 1.7
    else:  # never seen: the dense SVD, as before this module
        return dense(a.toarray(), singular)
    rng = np.random.default_rng(SEED)
    k = min(least + 2, nc)
    while True:
        x = np.linalg.qr(rng.standard_normal((nc, k)))[0]
        previous = None
        for iteration in range(MAX_ITERATIONS):
            x = np.linalg.qr(lu.solve(np.vstack([x, np.zeros((ng, k))]))[:nc])[0]
            null, vectors, sv = _ritz(a, x, threshold, least)
            # converged: the null directions' span no longer moves (at once for exact null
            # ones; a singular value counted as null by `singular` converges against the next)
            if previous is not None and iteration + 1 >= ITERATIONS and null == previous.shape[1]:
                span = vectors[:, :null]
                if np.abs(span - previous @ (previous.T @ span)).max(initial=0.0) <= SPAN_TOL:
                    break
            previous = vectors[:, :null]
        if null < k or k == nc:
            break
        k = min(2 * k, nc)  # every direction found is null: look at more
    share = np.sum(vectors[:, :null] ** 2, axis=1)
    rank = nc - null
    cond = smax / _smallest(lu, a, vectors[:, :null], shift, float(sv[null])) if rank == ng else np.inf
    return Analysis(rank, share, cond)


def _ritz(a, x: Array, threshold: float, least: int) -> tuple[int, Array, Array]:  # type: ignore[no-untyped-def]
    """Rayleigh-Ritz on span(x) (nc, k): how many of a's singular values there
    are null (at least `least`), the left singular vectors and the singular
    values, smallest first."""
    k = x.shape[1]
    w, sv, _ = np.linalg.svd((a.T @ x).T, full_matrices=False)  # of (k, ng)
    if sv.size < k:  # more vectors than coordinates: the rest of span(x) is null
        w = np.linalg.qr(w, mode="complete")[0]
        sv = np.concatenate([sv, np.zeros(k - sv.size)])
    order = np.argsort(sv, kind="stable")
    return max(int(np.sum(sv <= threshold)), least), x @ w[:, order], sv[order]


def dense(a: Array, singular: bool = False) -> Analysis:
    """`analyse` of a dense a by its SVD (what the sparse analysis reproduces)."""
    nc, ng = a.shape
    u, sv, _ = np.linalg.svd(a)
    smax = sv[0] if sv.size else 0.0
    rank = int(np.sum(sv > max(nc, ng) * EPS * smax))
    rank = min(rank, min(nc, ng) - 1) if singular else rank
    cond = float(smax / sv[-1]) if rank == ng and sv.size and sv[-1] > 0 else np.inf
    return Analysis(rank, np.sum(u[:, rank:] ** 2, axis=1), cond)


def _smallest(lu, a, null: Array, shift: float, ritz: float) -> float:  # type: ignore[no-untyped-def]
    """a's smallest singular value at full column rank: by Lanczos (ARPACK) on
    the inverse iteration's operator with the null directions projected out
    (its largest eigenvalue is 1 / (s_min^2 - shift^2)); the block's Ritz
    value `ritz` (an upper bound) should ARPACK not converge."""
    from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh

    nc, ng = a.shape

    def apply(v: Array) -> Array:
        v = v - null @ (null.T @ v)
        out = lu.solve(np.concatenate([v, np.zeros(ng)]))[:nc] / shift
        return out - null @ (null.T @ out)

    op = LinearOperator((nc, nc), matvec=apply, dtype=float)
    v0 = np.random.default_rng(SEED).standard_normal(nc)
    try:
        mu = float(eigsh(op, k=1, which="LA", v0=v0, return_eigenvectors=False)[0])
    except ArpackNoConvergence:
        return ritz
    return float(np.sqrt(1.0 / mu + shift ** 2)) if mu > 0 else ritz


class LeastSquares:
    """a (nc, ng; nc > ng, full column rank: scipy sparse) through the sparse
    LU of [[I, a], [a^T, 0]]: least squares of a x = b, and the minimum-norm
    y with a^T y = c (the dense path's thin QR, with nothing nc x ng).

    Attributes:
        rcond: 1 / sqrt of the 1-norm condition estimate of a^T a (Higham's,
            through the LU's solves): the order of 1 / cond(a), as the
            dense path's triangular estimate of R.

    Raises:
        RuntimeError: a is column-rank deficient (SuperLU's exactly singular).
    """

    def __init__(self, a) -> None:  # type: ignore[no-untyped-def]
        from scipy import sparse
        from scipy.sparse.linalg import LinearOperator, onenormest, splu

        a = a.tocsc()
        self.nc, self.ng = a.shape
        self.block = sparse.bmat([[sparse.identity(self.nc), a], [a.T, None]], format="csc")
        self.lu = splu(self.block)
        normal = LinearOperator((self.ng, self.ng), matvec=self._normal_inverse, rmatvec=self._normal_inverse,
                                dtype=float)
        anorm = float(np.asarray(abs(a.T @ a).sum(axis=0)).max(initial=0.0))
        with np.errstate(all="ignore"):
            inorm = float(onenormest(normal))
        product = anorm * inorm
        self.rcond = 1.0 / np.sqrt(product) if product > 0 and np.isfinite(product) else 0.0

    def _normal_inverse(self, v: Array) -> Array:
        """(a^T a)^-1 v: the block [[I, a], [a^T, 0]] [r; x] = [0; v] gives x = -(a^T a)^-1 v."""
        return -self.lu.solve(np.concatenate([np.zeros(self.nc), np.ravel(v)]))[self.nc:]

    def _solve(self, rhs: Array) -> Array:
        """The block system, with one step of iterative refinement: with I
        (not a multiple near a's smallest singular value, Bjorck's scaling,
        unknown here) beside a, the LU's solution carries a's condition number
        squared (the ladder of 100 with a redundant pin: its motor torque
        2e-13 off the closed form); one correction by the block's residual
        brings it to the dense QR's (8e-16)."""
        z = self.lu.solve(rhs)
        return z + self.lu.solve(rhs - self.block @ z)  # type: ignore[no-any-return]

    def solve(self, b: Array) -> Array:
        """x minimizing |a x - b| (size nc -> ng)."""
        return self._solve(np.concatenate([b, np.zeros(self.ng)]))[self.nc:]

    def solve_t(self, c: Array) -> Array:
        """The minimum-norm y with a^T y = c (size ng -> nc)."""
        return self._solve(np.concatenate([np.zeros(self.nc), c]))[:self.nc]


__all__ = ["Analysis", "LeastSquares", "analyse", "dense"]
