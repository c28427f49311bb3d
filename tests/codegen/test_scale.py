"""Large mechanisms: setup that holds nothing ng x ng, a generated solver
with a sparse pivoting fallback past the dense one's size limit, results as
the reference gives them."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from compare import assert_agree
from data_mechanisms import TWO_CABLES
from symid import api
from symid.codegen import model as code_model_module
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from symid.codegen.c import compose as c_compose
from symid.codegen.c import layout as c_layout
from symid.codegen.c import lu as c_lu
from symid.codegen.render import render
from symid.io.reader import load, loads
from symid.numeric import solve
from symid.numeric.reference import ReferenceEvaluator

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import ladder  # noqa: E402

needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")


@pytest.fixture
def no_dense_fallback(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Every generated C solver is built as past the dense fallback's limit, in a cache of its own."""
    monkeypatch.setattr(c_layout, "DENSE_LIMIT", 0)
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))


# slow: builds the two cables without the dense fallback; the sparse fallback's looped ladder stays in the quick
# tier
@pytest.mark.slow
@needs_cc
def test_without_dense_fallback_failing_pivots_are_solved_by_the_sparse_fallback(no_dense_fallback: None,
                                                                                 monkeypatch: pytest.MonkeyPatch,
                                                                                 tmp_path: Path) -> None:
    """Two cables: some fixed pivots fail on the way (the dense fallback's
    instants); past the dense limit the C solver refactors them with its
    sparse pivoting LU, in a workspace of the sparse factors' order, so no
    instant reaches the Python loop and the run matches the reference."""
    from symid.codegen.c import fallback as c_fallback

    handed: list[int] = []
    original = solve.Stepper.instant

    def spy(self: solve.Stepper, n: int, *args: object) -> solve.Instant:
        handed.append(n)
        return original(self, n, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(solve.Stepper, "instant", spy)
    mech = loads(TWO_CABLES, "two_cables.toml")
    model = code_model(mech)
    ng = model.flat.ng
    assert c_layout.work_size(model) == (len(model.flat.jac) + model.plan.size + c_fallback.work(model.plan, ng)
                                         + 12 * c_layout.stride(model))  # twelve work vectors
    assert c_fallback.work(model.plan, ng) < 13 * model.plan.size + 11 * ng  # linear: nothing ng x ng
    c_target.generate(model, tmp_path / "src")
    source = (tmp_path / "src" / "two_cables_solver.c").read_text()
    assert "dense_factor" not in source and "fb_factor" in source
    got = api.solve(mech, backend="c")
    assert got.error is None and len(handed) <= 1  # at most t0 (symid's own start) in the Python loop
    assert_agree(got.data, api.solve(mech, backend="reference").data)


def test_setup_of_a_large_ladder_allocates_nothing_ng_by_ng(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Past DENSE_SETUP coordinates the plan is sampled entry by entry: no
    dense Phi_q, no array of ng^2 / 4 numbers or more, and a workspace of
    the sparse factors' size."""
    from symid.codegen.c import fallback as c_fallback

    n = 26
    ng = ladder.Ladder(n).ng
    assert ng > code_model_module.DENSE_SETUP and ng > 0
    largest = [0]
    for fn in ("zeros", "empty", "ones", "full", "eye", "identity"):
        original = getattr(np, fn)

        def tracked(*args: object, _original=original, **kwargs: object) -> np.ndarray:  # type: ignore[no-untyped-def]
            out = _original(*args, **kwargs)
            largest[0] = max(largest[0], out.size)
            return out

        monkeypatch.setattr(np, fn, tracked)

    def dense(*args: object) -> None:
        raise AssertionError("dense Phi_q during setup")

    monkeypatch.setattr(ReferenceEvaluator, "phi_q", dense)
    monkeypatch.setattr(c_layout, "DENSE_LIMIT", code_model_module.DENSE_SETUP)
    model = code_model(load(ladder.write(n, tmp_path)))
    assert largest[0] < ng * ng // 4
    assert model.plan.size < 10 * ng and not model.plan.singular
    fallback = c_fallback.work(model.plan, ng)  # the sparse pivoting fallback's, linear in the factors
    assert fallback < 13 * model.plan.size + 11 * ng and c_layout.work_size(model) < 48 * ng + fallback  # 12 work vectors (stride ~ng+pad), Phi_q, LU


@pytest.mark.parametrize("seed", range(3))
def test_scaling_from_entries_is_the_dense_scaling(seed: int) -> None:
    from symid.numeric.sparse_scaling import scaling_of_entries
    from symid.numeric.stability import Scaling

    rng = np.random.default_rng(seed)
    n = 30
    jac = np.where(rng.random((n, n)) < 0.2, rng.normal(size=(n, n)) * 10.0 ** rng.integers(-3, 3, (n, n)), 0.0)
    q = rng.normal(size=n)
    r, c = np.nonzero(jac)
    dense, entries = Scaling.of(jac, q), scaling_of_entries(r, c, jac[r, c], q, n)
    for field in ("lref", "col", "row", "dc", "dr", "inv_col", "inv_row"):
        assert np.array_equal(getattr(dense, field), getattr(entries, field)), field


@pytest.fixture
def looped(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Every family group of MIN_MEMBERS or more is looped, in a cache of its own."""
    from symid.codegen.c import loops as c_loops

    monkeypatch.setattr(c_loops, "LOOP_MIN", 0)
    monkeypatch.setattr(c_lu, "LU_TABLES_MIN", 0)
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))


@pytest.mark.slow  # compiles a looped 25-body ladder; the sparse fallback's looped ladder stays in the quick tier
@needs_cc
def test_looped_kernels_agree_with_reference(looped: None, no_dense_fallback: None, tmp_path: Path) -> None:
    """A ladder of 12 solved by C with its revolutes looped, its LU rolled
    into runs (c_lu_runs; tests/codegen/test_lu_runs.py: bitwise the tables'
    results) and no dense fallback: every column within 1e-12 of its peak
    of the reference's (some reactions asked: the loops skip the others)."""
    reactions = 'reactions = ["pivot3", "left2", "right5", "motor"]'
    text = ladder.toml(ladder.Ladder(12, x0=0.3), steps=25).replace('kind = "inverse_dynamics"',
                                                                    'kind = "inverse_dynamics"\n' + reactions)
    mech = loads(text, "ladder_12.toml")
    model = code_model(mech, looped=True)  # the looped members' rows and reactions are not substituted
    ctx = c_target.context(model)
    assert "phi_q 2" in "\n".join(f"{fn.name} {len(fn.loops)}" for fn in ctx.functions)
    assert "reactions 2" in "\n".join(f"{fn.name} {len(fn.loops)}" for fn in ctx.functions)
    source = render("c/solver.c.j2", **ctx.namespace())
    assert "int r;" in source and "symid_looped_output" not in source
    got = api.solve(mech, backend="c")
    expected = api.solve(mech, backend="reference")
    assert got.error is None and got.columns == expected.columns
    assert_agree(got.data, expected.data)


def test_looped_kernels_do_not_grow_with_the_number_of_bays(looped: None, tmp_path: Path) -> None:
    """The looped functions' code and the LU's are the same for 8 and 16
    bays but for numbers (trip counts, run lengths, indices) and names: only
    the tables grow, where there are tables (the members and the LU's steps
    repeat as runs here)."""
    import re

    def loop_code(n: int) -> str:
        model = code_model(load(ladder.write(n, tmp_path / str(n))))
        c_target.generate(model, tmp_path / f"src{n}")
        text = (tmp_path / f"src{n}" / f"ladder_{n}_solver.c").read_text()
        kernels = re.findall(r"^static (?:void|int) ladder_\d+_(?:\w+_L\d+|sparse_\w+)\(.*?^}", text, re.S | re.M)
        assert len(kernels) > 8
        return re.sub(r"(?i)ladder_\d+|\b\d+u?\b", "X", "\n".join(kernels))  # sizes: 99 or 99u (MISRA 10.4)

    small, large = loop_code(8), loop_code(16)
    assert small and small == large


@needs_cc
def test_sparse_fallback_alone_solves_a_looped_ladder_as_the_reference(looped: None, no_dense_fallback: None,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A ladder of 10 (looped kernels, LU on tables, no dense fallback) with
    the C threshold test set above 1: every fixed pivot fails it, so every
    factorization is the sparse fallback's (partial pivoting, the plan's row
    never preferred). No instant past t0 reaches the Python loop, so the
    fallback's workspace sufficed, and the run matches the reference."""
    handed: list[int] = []
    original = solve.Stepper.instant

    def spy(self: solve.Stepper, n: int, *args: object) -> solve.Instant:
        handed.append(n)
        return original(self, n, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(solve.Stepper, "instant", spy)
    monkeypatch.setattr(c_compose, "THRESHOLD", 2.0)
    mech = loads(ladder.toml(ladder.Ladder(10, x0=0.3), steps=15), "ladder_10.toml")
    got = api.solve(mech, backend="c")
    assert got.error is None and len(handed) <= 1
    assert_agree(got.data, api.solve(mech, backend="reference").data)
