"""The NumPy sweep vectorized over variants (symid.study.batch_numpy): the
variants it keeps have the figures of their own `symid solve --set` run, the
ones it cannot vouch for are handed back and end as their own solve ends,
and its batched LU solves as a dense solver does."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from symid import api
from symid.output.summary import efforts, summarize
from symid.study import batch_numpy
from symid.study.batch_lu import Factors, Plan
from symid.study.engine import solve_figures
from symid.study.figures import STATUS
from symid.study.variants import base_matrix, study_mechanism
from symid.symbolic.constraints import TYPES as CONSTRAINTS

STEPS = 31
# (example, varied base parameters, their values: the grid is their product)
GRIDS = [
    ("slider_crank", ("L_rod", "n", "m_slider"), ((0.27, 0.4), (3.0, 7.0), (0.8, 1.6))),  # omega = 2 pi n derived
    ("four_bar", ("L_coupler", "m_rocker"), ((0.33, 0.37), (0.5, 0.9))),
    ("excavator", ("a_boom", "m_bucket"), ((0.2, 0.3), (400.0, 600.0))),  # distance drivers: effort -2 |f| lambda
    ("quick_return", ("r_crank",), ((0.08, 0.1),)),
]


def own(example: str, names: tuple[str, ...], row: np.ndarray, steps: int = STEPS):
    """The variant's own run on the NumPy backend, as `symid solve --set` makes it."""
    values = {n: repr(float(v)) for n, v in zip(names, row)}
    return api.prepare(api.example(example), "numpy", set_values=values, steps=steps).solve()


def own_figures(mech, results) -> np.ndarray:
    """The contract's figures from a solved table (summary efforts, reaction magnitudes)."""
    out = []
    for e in efforts(results.mechanism, results):
        s = summarize(e)
        out += [s.peak, s.t_peak, s.rms, float(np.max(np.abs(e.power)))]
    for c in mech.constraints:
        out.append(max(float(np.max(np.hypot(results[f"{c.name}.Fx_{r}"], results[f"{c.name}.Fy_{r}"])))
                       for r in CONSTRAINTS[c.type].roles))
    return np.array(out)


def assert_close(got: np.ndarray, want: np.ndarray) -> None:
    # a force zero by construction (a motor's reaction) may be a few rounding errors of the others
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * float(np.max(np.abs(want))))


@pytest.mark.parametrize("example, names, axes", GRIDS, ids=[g[0] for g in GRIDS])
def test_the_vectorized_loop_keeps_every_variant_with_its_own_solves_figures(example, names, axes):
    mech = api.load_mechanism(api.example(example), steps=STEPS)
    study = study_mechanism(mech)
    base = np.array(list(itertools.product(*axes)))
    batch = batch_numpy.run(study, base_matrix(study, names, base), chunk=3)  # chunks of 3: several, one short
    assert list(batch.status) == [0] * len(base)  # solved in the vector, none handed back
    assert list(batch.solved) == [STEPS] * len(base)
    figures = solve_figures(mech, names, base, "numpy")
    for k, row in enumerate(base):
        results = own(example, names, row)
        assert results.error is None
        want = own_figures(mech, results)
        assert_close(batch.values[k], want)
        assert_close(figures.values[k], want)
        assert batch.t_end[k] == figures.t_end[k] == results.data[-1, 0]


def test_variants_the_vector_cannot_vouch_for_go_back_and_end_as_their_own_solves():
    # a rod shorter than the crank (0.1) cannot reach the guide past a quarter
    # turn (Newton fails); one a hair longer passes a toggle position there,
    # (an instant of a 41-step grid), a step the jump check flags and symid
    # decides in sub-steps
    steps = 41
    mech = api.load_mechanism(api.example("slider_crank"), steps=steps)
    study = study_mechanism(mech)
    base = np.array([[0.3], [0.05], [0.1000001], [0.35]])
    batch = batch_numpy.run(study, base_matrix(study, ("L_rod",), base))
    assert list(batch.status) == [0, batch_numpy.RETRY, batch_numpy.RETRY, 0]
    assert 0 < batch.solved[1] < steps and 0 < batch.solved[2] < steps
    figures = solve_figures(mech, ("L_rod",), base, "numpy")
    for k, row in enumerate(base):
        results = own("slider_crank", ("L_rod",), row, steps)
        assert (STATUS[figures.status[k]] == "ok") == (results.error is None) == (k in (0, 3))
        assert figures.t_end[k] == results.data[-1, 0]  # a failed variant: the last instant solved
        assert_close(figures.values[k], own_figures(mech, results))
    assert STATUS[figures.status[2]] == "jump"


def test_a_variant_with_a_non_finite_derived_parameter_goes_back():
    mech = api.load_mechanism(api.example("slider_crank"), steps=5)
    study = study_mechanism(mech)
    base = np.array([[5.0], [np.inf]])  # omega = 2 pi n
    batch = batch_numpy.run(study, base_matrix(study, ("n",), base))
    assert list(batch.status) == [0, batch_numpy.RETRY] and batch.solved[1] == 0


def test_the_batched_lu_in_a_fixed_pivot_order_solves_as_a_dense_solver():
    rng = np.random.default_rng(14)
    n, k = 7, 5
    rows, cols = rng.permutation(n), rng.permutation(n)
    pattern = rng.random((n, n)) < 0.4
    pattern[rows, cols] = True
    a = np.where(pattern, rng.normal(size=(k, n, n)), 0.0)
    a[:, rows, cols] += 10.0  # pivots that pass the threshold test
    r, c = np.nonzero(pattern)
    factors = Factors(Plan(r, c, rows, cols), a[:, r, c].T, 0.1)
    assert factors.ok.all()
    b = rng.normal(size=(n, k))
    want = np.linalg.solve(a, b.T[..., None])[..., 0].T
    want_t = np.linalg.solve(np.swapaxes(a, 1, 2), b.T[..., None])[..., 0].T
    # batched LU against numpy's LAPACK on well-conditioned random systems: rounding (both)
    np.testing.assert_allclose(factors.solve(b), want, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(factors.solve_t(b), want_t, rtol=1e-12, atol=1e-14)
    # a pivot below a tenth of an entry under it fails the module's test
    a[0, rows[0], cols[0]] = 1e-3
    a[0, rows[1], cols[0]] = 1.0
    pattern[rows[1], cols[0]] = True
    r, c = np.nonzero(pattern)
    assert list(Factors(Plan(r, c, rows, cols), a[:, r, c].T, 0.1).ok) == [False] + [True] * (k - 1)


RAIL = """
[mechanism]
name = "rail"
gravity = [0.0, -9.81]
[parameters]
A = 0.2
w = 3.0
[analysis]
t0 = 0.0
t1 = 2.0
steps = 21
[[body]]
name = "block"
mass = 2.0
inertia = 0.01
q0 = [0.0, 0.0, 0.0]
[[constraint]]
name = "rail"
type = "translational"
i = "ground"
j = "block"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
friction = { mu = 0.3, viscous = 0.7, arm = 0.1, v_smooth = 0.01 }
[[constraint]]
name = "push"
type = "coordinate_driver"
body = "block"
coordinate = "x"
f = "A*sin(w*t)"
"""


def test_joint_friction_is_left_to_the_normal_path(tmp_path):
    # the module's loop does not solve friction (the Python loop does): the
    # vector must not take such a study, or the friction force would be missing
    with_friction, without = tmp_path / "rail.toml", tmp_path / "smooth_rail.toml"
    with_friction.write_text(RAIL)
    without.write_text("\n".join(line for line in RAIL.splitlines() if not line.startswith("friction")))
    assert not batch_numpy.usable(study_mechanism(api.load_mechanism(with_friction)))
    assert batch_numpy.usable(study_mechanism(api.load_mechanism(without)))


def test_a_chunk_of_few_long_variants_takes_the_modules_own_loop(monkeypatch):
    """A long run leaves few variants per chunk; the vectorized loop costs ~3.3 ms
    a step whatever K (a variant of 20001 instants took 82 s), the module's own
    loop ~0.07 ms an instant: below NUMPY_BATCH_MIN variants the chunk takes it,
    and its figures are the C engine's (an independent loop)."""
    from symid.study import engine

    def vectorized(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("a chunk of one variant went through the vectorized loop")

    mech = api.load_mechanism(api.example("slider_crank"), steps=2001)
    c = solve_figures(mech, ("n",), np.array([[5.0], [6.0]]), "c")
    monkeypatch.setattr(batch_numpy, "run", vectorized)
    few = np.array([[5.0], [6.0]])
    assert len(few) < engine.NUMPY_BATCH_MIN
    figures = solve_figures(mech, ("n",), few, "numpy")
    assert list(figures.status) == [0, 0]
    # both solve each instant to tol 1e-12: the figures agree to rounding
    np.testing.assert_allclose(figures.values, c.values, rtol=1e-9, atol=1e-9 * float(np.max(np.abs(c.values))))
