"""The rank analysis of a large Phi_q with nothing nc x ng
(`symid.numeric.sparse_rank`, from `SPARSE_MIN` coordinates): the rank, the
dependent rows and the condition number of the dense SVD, the redundancy
errors and warnings word for word as the dense path words them on a small
mechanism, and minimum-norm runs. On the ladder of 100 four-bars
(`benchmarks/ladder.py`: ng 603, just past SPARSE_MIN, exact torque) with a
planted redundant row."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from scipy import sparse

from benchmarks import ladder
from symid import api, backends
from symid.backends import footprint
from symid.backends.prepare import prepare
from symid.cli import main
from symid.numeric import sparse_rank
from symid.numeric.redundancy import rank_of
from symid.numeric.reference import ReferenceEvaluator
from symid.numeric.stability import NULL_SHARE, SPARSE_MIN, Factor, Scaling
from symid.symbolic.assemble import assemble

LARGE, SMALL = 100, 4  # ng 603 (sparse) and 27 (dense)
BRACE = ('\n[[constraint]]\nname = "brace"\ntype = "revolute"\ni = "coupler0"\nj = "rocker1"\n'
         'si = ["b/2", 0.0]\nsj = ["a/2", 0.0]\n')  # a second pin where right0 pins: two rows too many
MOTOR2 = ('\n[[constraint]]\nname = "motor2"\ntype = "relative_angle_driver"\ni = "ground"\nj = "rocker1"\n'
          'f = "theta0 + A*sin(w*t)"\nC = 0.0\n')  # rocker1 turns with rocker0 already: one row too many
MESSAGES = {
    "brace": "{path}: [[constraint]]: {nc} constraint rows for {ng} coordinates: 2 extra: the rows of right0, "
             "brace are dependent at t0 (rank {ng}); redundant = \"min_norm\" solves anyway, with minimum-norm "
             "multipliers",
    "motor2": "{path}: [[constraint]]: {nc} constraint rows for {ng} coordinates: 1 extra: driver motor2 is one "
              "too many (or motor: each alone drives what the other rows leave free); the rows of pivot0, pivot1, "
              "left0, right0, motor, motor2 are dependent at t0 (rank {ng}); redundant = \"min_norm\" solves "
              "anyway, with minimum-norm multipliers",
}


def write(folder: Path, n: int, extra: str, min_norm: bool = False) -> Path:
    text = ladder.toml(ladder.Ladder(n), steps=11) + extra
    if min_norm:
        text = text.replace('kind = "inverse_dynamics"', 'kind = "inverse_dynamics"\nredundant = "min_norm"')
    path = folder / f"ladder_{n}.toml"
    path.write_text(text)
    return path


@pytest.fixture
def no_dense(monkeypatch: pytest.MonkeyPatch) -> None:
    """Building a dense Phi_q of the reference evaluator raises (the rank
    analysis and the redundancy report use its sparse one)."""
    def dense(self: ReferenceEvaluator, q: np.ndarray, t: float) -> np.ndarray:
        if self.layout.ng >= SPARSE_MIN:
            raise AssertionError("a dense Phi_q was built")
        return original(self, q, t)
    original = ReferenceEvaluator.phi_q
    monkeypatch.setattr(ReferenceEvaluator, "phi_q", dense)


@pytest.mark.parametrize("planted", ["brace", "motor2"])
def test_a_planted_redundant_row_is_named_large_as_the_dense_path_names_it_small(
        planted: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], no_dense: None) -> None:
    extra = {"brace": BRACE, "motor2": MOTOR2}[planted]
    for n in (SMALL, LARGE):
        (tmp_path / str(n)).mkdir()
        path = write(tmp_path / str(n), n, extra)
        layout = assemble(api.load_mechanism(path))
        assert (layout.ng >= SPARSE_MIN) == (n == LARGE)
        status = main(["check", str(path)])
        line = " ".join(capsys.readouterr().err.split())
        assert status == 2 and line == "symid: " + MESSAGES[planted].format(path=path, nc=layout.nc, ng=layout.ng), line


def test_a_minimum_norm_run_of_a_large_mechanism_builds_nothing_dense(tmp_path: Path, no_dense: None) -> None:
    """redundant = "min_norm" on the Python loop: the warning as the dense path
    words it, the closed form's motor torque, and the two identical pins'
    minimum-norm multipliers equal (the load shared evenly)."""
    path = write(tmp_path, LARGE, BRACE, min_norm=True)
    res = api.solve(path, backend="reference", outputs=["q", "qdot", "qddot", "lambda", "reactions", "cond"])
    assert res.error is None, res.error
    assert res.warnings == [f"redundant constraints: the rows of right0, brace are dependent (rank {6 * LARGE + 3} "
                            f"of {6 * LARGE + 5} rows); their multipliers and reactions are the minimum-norm ones, "
                            "not unique; the kinematics, the drive torques and the other reactions are unique"]
    exact = ladder.Ladder(LARGE).torque(res["t"])
    # Newton converges quadratically past its tolerance, so the torque is the multipliers' rounding
    # through 201 bodies: 8e-16 measured (the dense QR's 6e-15; the sparse LU without its refinement 2e-13)
    assert np.max(np.abs(res["motor.T_j"] - exact)) <= 2e-14 * np.max(np.abs(exact))
    for column in ("Fx_i", "Fy_i"):
        np.testing.assert_allclose(res[f"brace.{column}"], res[f"right0.{column}"], rtol=1e-12,
                                   atol=1e-12 * np.max(np.abs(res["right0.Fy_i"])))
    assert np.all(np.isfinite(res["cond"])) and np.all(res["cond"] > 1)


def phi_q_of(n: int, folder: Path) -> tuple[sparse.csr_matrix, np.ndarray]:
    """Phi_q of the plain ladder of n at t = 0.3, and q there."""
    path = ladder.write(n, folder, steps=11)
    q = ladder.Ladder(n).q_exact(0.3)
    return prepare(api.load_mechanism(path), "reference").evaluator.phi_q_sparse(q, 0.3).tocsr(), q


@pytest.fixture(scope="module")
def phi_q(tmp_path_factory: pytest.TempPathFactory) -> tuple[sparse.csr_matrix, np.ndarray]:
    return phi_q_of(LARGE, tmp_path_factory.mktemp("ladder"))


@pytest.fixture(scope="module")
def phi_q_30(tmp_path_factory: pytest.TempPathFactory) -> tuple[sparse.csr_matrix, np.ndarray]:
    """The ladder of 30 (ng 183): `analyse` is the same code at any size, and
    numpy's SVD of 603 columns, the truth, took 5 s on a loaded machine."""
    return phi_q_of(30, tmp_path_factory.mktemp("ladder30"))


def planted(jac: sparse.csr_matrix, how: str) -> sparse.csr_matrix:
    if how == "a row repeated":
        return sparse.vstack([jac, jac[5]]).tocsr()
    if how == "a row combined":
        return sparse.vstack([jac, jac[4] + 2 * jac[7]]).tocsr()
    if how == "square, a row replaced":
        return sparse.vstack([jac[:5], jac[4] + jac[7], jac[6:]]).tocsr()
    return jac


@pytest.mark.parametrize("how", ["none", "a row repeated", "a row combined", "square, a row replaced"])
@pytest.mark.parametrize("singular", [False, True])
def test_the_sparse_analysis_is_the_dense_svds(phi_q_30, how: str, singular: bool) -> None:
    """Rank, the rows of the left null space (the projector's diagonal, which
    no basis changes) and the 2-norm condition number, against numpy's SVD of
    the same equilibrated matrix; `singular` counts the smallest singular
    value as null (a factorization found the matrix singular)."""
    jac, q = phi_q_30
    jac = planted(jac, how)
    scaling = Scaling.of(jac.toarray(), q)
    a = jac.toarray() / scaling.row[:, None] * scaling.col[None, :]
    truth = sparse_rank.dense(a, singular)
    got = sparse_rank.analyse(sparse.csr_matrix(a), singular)
    assert got.rank == truth.rank

    def rows(share: np.ndarray) -> list[int]:
        return list(np.flatnonzero(share > NULL_SHARE * share.max())) if share.max() > 0 else []
    assert rows(got.share) == rows(truth.share) and (rows(truth.share) != []) == (how != "none" or singular)
    # the shares: an exactly null direction's to rounding (1e-16 measured); a smallest singular value
    # counted as null by `singular` converges against the next one, its vector to 2e-9 (measured: the
    # rounding of the null directions, grown 1 / shift^2 a solve); the 1e-4 cut's names are the SVD's
    np.testing.assert_allclose(got.share, truth.share, rtol=0, atol=1e-8)
    if np.isfinite(truth.cond):
        assert got.cond == pytest.approx(truth.cond, rel=1e-8)  # ARPACK's tolerance on converged Ritz values
    else:
        assert got.cond == np.inf


def test_the_sparse_least_squares_factor_solves_as_the_dense_qr(phi_q) -> None:
    """Redundant rows (nc > ng) from SPARSE_MIN on: least squares and
    minimum-norm multipliers through the sparse block LU, as the dense thin QR."""
    jac, q = phi_q
    jac = planted(jac, "a row combined")
    scaling = Scaling.of(jac.toarray(), q)
    sparse_factor, dense_factor = Factor(jac.tocsc(), scaling), Factor(jac.toarray(), scaling)
    assert sparse_factor.lsq is not None
    rng = np.random.default_rng(31)
    b, c = rng.standard_normal(jac.shape[0]), rng.standard_normal(jac.shape[1])
    for solve in ("solve", "solve_t"):
        rhs = b if solve == "solve" else c
        truth = getattr(dense_factor, solve)(rhs)
        # cond ~ 360 times eps, with room for the loads' spread of sizes
        np.testing.assert_allclose(getattr(sparse_factor, solve)(rhs), truth, rtol=0,
                                   atol=1e-11 * np.max(np.abs(truth)))
    # both are 1-norm estimates of the scaled matrix's conditioning, of different matrices (R; a^T a's root)
    assert dense_factor.cond / 30 <= sparse_factor.cond <= dense_factor.cond


def test_the_redundant_rows_of_a_large_mechanism_count_nothing_dense(tmp_path: Path) -> None:
    """The memory estimate has no nc x ng part from SPARSE_MIN coordinates on,
    redundant rows or not (a small one keeps its 5 dense copies); and the rank
    analysis's own arrays stay below a quarter of one dense Phi_q (0.11 measured:
    the block matrix's entries, blocks of a few vectors; the dense SVD holds U,
    nc x nc, and more; tracemalloc sees numpy's arrays, not SuperLU's factors)."""
    from symid.model.params import parameter_values
    from symid.numeric.evaluator import Needs

    (tmp_path / "small").mkdir()
    small = assemble(api.load_mechanism(write(tmp_path / "small", SMALL, BRACE)))
    large = assemble(api.load_mechanism(write(tmp_path, LARGE, BRACE)))
    assert large.nc > large.ng >= SPARSE_MIN
    for backend in backends.names():
        assert footprint.estimate(large, backend).dense_mb == 0, backend
        assert footprint.estimate(small, backend).dense_mb == pytest.approx(
            footprint.DENSE_COPIES * 8 * small.nc * small.nc / 2**20, rel=1e-12), backend
    values = parameter_values(large.mechanism.parameters)
    q = ladder.Ladder(LARGE).q_exact(0.3)
    jac = ReferenceEvaluator(large, values, Needs(velocity=False)).phi_q_sparse(q, 0.3)
    scaling = Scaling.of(jac, q)
    rank_of(jac, scaling, large)  # scipy's modules imported, ARPACK's first call made
    tracemalloc.start()
    try:
        rank = rank_of(jac, scaling, large)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (rank.rank, rank.dependent) == (large.ng, ("right0", "brace"))
    assert peak < 0.25 * 8 * large.nc * large.ng, peak
