"""The Python loop's checks of a large Phi_q without anything nc x ng
(`symid.numeric.stability.SPARSE_MIN` on): SuperLU solves, the condition
estimate and the singular verdict, against dense linear algebra, on the
ladder of 100 four-bars (`benchmarks/ladder.py`: ng 603, exact torque)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import sparse

from benchmarks import ladder
from symid import api
from symid.backends.prepare import prepare
from symid.numeric.stability import SINGULAR_RCOND, SPARSE_MIN, Factor, Scaling
from tiers import first_quick

N = 100  # ng 603: just past SPARSE_MIN
OUTPUTS = ["q", "qdot", "qddot", "lambda", "reactions", "cond"]


@pytest.fixture(scope="module")
def path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    assert ladder.Ladder(N).ng >= SPARSE_MIN
    return ladder.write(N, tmp_path_factory.mktemp("ladder"), steps=11)


def dense_and_sparse(path: Path, t: float) -> tuple[np.ndarray, object, np.ndarray]:
    solver = prepare(api.load_mechanism(path), "reference")
    q = ladder.Ladder(N).q_exact(t)
    return solver.evaluator.phi_q(q, t), solver.evaluator.phi_q_sparse(q, t), q


def test_sparse_factor_solves_and_estimates_like_dense_algebra(path: Path) -> None:
    jac, jac_sparse, q = dense_and_sparse(path, 0.3)
    assert sparse.issparse(jac_sparse) and np.array_equal(jac_sparse.toarray(), jac)
    scaling = Scaling.of(jac, q)
    factor = Factor(jac_sparse, scaling)
    b = np.random.default_rng(31).standard_normal(jac.shape[0])
    # 1e-10: cond ~ 1e3 times eps, with room for the loads' spread of sizes
    np.testing.assert_allclose(factor.solve(b), np.linalg.solve(jac, b), rtol=0,
                               atol=1e-10 * np.max(np.abs(np.linalg.solve(jac, b))))
    np.testing.assert_allclose(factor.solve_t(b), np.linalg.solve(jac.T, b), rtol=0,
                               atol=1e-10 * np.max(np.abs(np.linalg.solve(jac.T, b))))
    a = jac * scaling.dr[:, None] * scaling.dc
    exact = np.linalg.cond(a, 1)
    # Higham's estimate of the inverse's norm is a lower bound, in practice within a factor 3
    assert exact / 3 <= factor.cond <= exact * (1 + 1e-9), (factor.cond, exact)


def test_a_dependent_row_is_singular_sparse_as_dense(path: Path) -> None:
    jac, _, q = dense_and_sparse(path, 0.3)
    jac = jac.copy()
    jac[5] = jac[4] + jac[7]  # a row the others give: rank ng - 1
    scaling = Scaling.of(jac, q)
    assert Factor(sparse.csc_matrix(jac), scaling).rcond <= SINGULAR_RCOND
    assert Factor(jac, scaling).rcond <= SINGULAR_RCOND


@pytest.mark.parametrize("backend", first_quick(["reference", "numpy", "casadi"]))  # one Python loop, three evaluators
def test_the_python_loop_of_a_large_mechanism_holds_nothing_nc_by_ng(path: Path, backend: str,
                                                                     monkeypatch) -> None:
    """The cond column asks for the Python loop at every instant; the dense Phi_q is
    never built (it raises here), the torque is the closed form's and cond the
    dense 1-norm condition of the equilibrated matrix."""
    from symid import backends

    evaluator_type = type(prepare(api.load_mechanism(path), backend).evaluator)

    def dense(*_: object) -> None:
        raise AssertionError("a dense Phi_q was built")
    monkeypatch.setattr(evaluator_type, "phi_q", dense)
    res = api.solve(path, backend=backend, outputs=OUTPUTS)
    assert res.error is None, res.error
    exact = ladder.Ladder(N).torque(res["t"])
    # 1e-12 of the peak: Newton's tolerance through 201 bodies' multipliers
    assert np.max(np.abs(res["motor.T_j"] - exact)) <= 1e-12 * np.max(np.abs(exact))
    monkeypatch.undo()
    ref = prepare(api.load_mechanism(path), "reference").evaluator
    q0 = ladder.Ladder(N).q_exact(0.0)
    scaling = Scaling.of(ref.phi_q(q0, 0.0), q0)  # the run's: from Phi_q at the assembled t0
    for k in (0, 5, 10):
        t = float(res["t"][k])
        a = ref.phi_q(ladder.Ladder(N).q_exact(t), t) * scaling.dr[:, None] * scaling.dc
        cond = np.linalg.cond(a, 1)
        assert cond / 3 <= res["cond"][k] <= cond * (1 + 1e-6), (k, res["cond"][k], cond)
    assert backends.capabilities(backend).compiled_loop is False


@pytest.mark.slow  # the dense rank and condition of a large mechanism, for the comparison
def test_symid_check_of_a_large_mechanism_gives_the_dense_rank_and_condition(path: Path, monkeypatch) -> None:
    """Rank and 2-norm condition number of the equilibrated Phi_q by Lanczos on
    the sparse matrix and its LU, against numpy's SVD of the dense one."""
    from symid.tools.check import check

    study = api.prepare(path, "numpy")

    def dense(*_: object) -> None:
        raise AssertionError("a dense Phi_q was built")
    monkeypatch.setattr(type(study.evaluator), "phi_q", dense)
    report = check(study)
    monkeypatch.undo()
    assert report.rank == report.ng == 6 * N + 3 and report.dependent == ()
    q0 = ladder.Ladder(N).q_exact(0.0)
    jac = prepare(api.load_mechanism(path), "reference").evaluator.phi_q(q0, 0.0)
    scaling = Scaling.of(jac, q0)
    exact = np.linalg.cond(jac / scaling.row[:, None] * scaling.col[None, :], 2)
    # ARPACK's default tolerance is machine precision on converged Ritz values: 1e-8 leaves room
    assert report.cond == pytest.approx(exact, rel=1e-8)
