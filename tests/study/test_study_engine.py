"""The batch engine of design studies (symid.study.engine): every variant's
figures are those of its own single solve, a failing variant keeps its row,
and the threads do not change a bit."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from symid import api
from symid.errors import InputError
from symid.model.mechanism import Mechanism
from symid.output.summary import efforts, summarize
from symid.study.engine import solve_figures
from symid.study.figures import STATUS
from symid.symbolic.constraints import TYPES as CONSTRAINTS

STEPS = 41
# (example, varied base parameters, their values: the grid is their product)
GRIDS = {
    "slider_crank": (("L_rod", "n"), ((0.25, 0.4), (3.0, 5.0, 8.0))),
    "four_bar": (("L_coupler", "m_rocker"), ((0.33, 0.37), (0.5, 0.9))),
    # hydraulic cylinders: distance drivers, whose effort is -2 |f| lambda
    "excavator": (("a_boom", "m_bucket"), ((0.2, 0.3), (500.0,))),
}


def grid(example: str) -> tuple[Mechanism, tuple[str, ...], np.ndarray]:
    names, axes = GRIDS[example]
    mech = api.load_mechanism(api.example(example), steps=STEPS)
    return mech, names, np.array(list(itertools.product(*axes)))


def own_solve(example: str, backend: str, names: tuple[str, ...], row: np.ndarray):
    """The variant's own run, as `symid solve --set` makes it."""
    values = {n: repr(float(v)) for n, v in zip(names, row)}
    return api.prepare(api.example(example), backend, set_values=values, steps=STEPS).solve()


def own_figures(mech: Mechanism, results) -> tuple[np.ndarray, str]:
    """The contract's figures from a solved table: the summary's efforts, and
    the reaction forces' magnitudes read from the table's columns."""
    out = []
    for e in efforts(results.mechanism, results):
        s = summarize(e)
        out += [s.peak, s.t_peak, s.rms, float(np.max(np.abs(e.power)))]
    for c in mech.constraints:
        roles = CONSTRAINTS[c.type].roles
        out.append(max(float(np.max(np.hypot(results[f"{c.name}.Fx_{r}"], results[f"{c.name}.Fy_{r}"])))
                       for r in roles))
    return np.array(out), "ok" if results.error is None else "failed"


def assert_close(got: np.ndarray, want: np.ndarray) -> None:
    # relative 1e-12; a force that is zero by construction (a motor's
    # reaction force) may come out as a few rounding errors of the others
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * float(np.max(np.abs(want))))


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("example", sorted(GRIDS))
def test_every_variants_figures_equal_those_of_its_own_solve(example, backend):
    mech, names, base = grid(example)
    figures = solve_figures(mech, names, base, backend, workers=2)
    assert len(figures) == len(base) and np.all(figures.status == 0)
    assert np.all(figures.t_end == mech.analysis.t1)
    for k, row in enumerate(base):
        want, state = own_figures(mech, own_solve(example, backend, names, row))
        assert state == "ok"
        assert_close(figures.values[k], want)


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_a_failing_variant_keeps_its_row_and_status_while_the_others_are_right(backend):
    # a rod shorter than the crank (0.1) cannot reach the slider's guide past
    # a quarter turn: that variant stops, the next ones run on
    mech = api.load_mechanism(api.example("slider_crank"), steps=STEPS)
    base = np.array([[0.3], [0.05], [0.35]])
    figures = solve_figures(mech, ("L_rod",), base, backend)
    assert [STATUS[s] for s in figures.status[[0, 2]]] == ["ok", "ok"]
    assert STATUS[figures.status[1]] in ("not_converged", "singular", "jump", "nonfinite")
    for k in range(3):
        results = own_solve("slider_crank", backend, ("L_rod",), base[k])
        want, state = own_figures(mech, results)
        assert state == ("failed" if k == 1 else "ok")
        assert figures.t_end[k] == results.data[-1, 0]  # the last instant solved
        assert_close(figures.values[k], want)  # failed: the figures of the instants before
    assert figures.t_end[1] < mech.analysis.t1


def test_one_and_two_threads_give_identical_arrays():
    mech = api.load_mechanism(api.example("slider_crank"), steps=STEPS)
    rng = np.random.default_rng(14)
    base = np.column_stack([rng.uniform(0.25, 0.45, 9), rng.uniform(2.0, 10.0, 9)])
    one = solve_figures(mech, ("L_rod", "n"), base, "c", workers=1)
    two = solve_figures(mech, ("L_rod", "n"), base, "c", workers=2)
    assert one.names == two.names
    assert np.array_equal(one.values, two.values) and np.array_equal(one.status, two.status)
    assert np.array_equal(one.t_end, two.t_end)


@pytest.mark.parametrize("name, message", [
    ("omega", r"variants: 'omega' is a derived parameter \(omega = 2\*pi\*n\): vary the base parameters it is "
              r"defined from \(n\)"),
    ("rpm", r"variants: no parameter 'rpm' \(base parameters: L_crank"),
    ("n,n", r"variants: parameter 'n' is varied twice"),
])
def test_varying_a_derived_unknown_or_repeated_parameter_is_an_input_error(name, message):
    mech = api.load_mechanism(api.example("slider_crank"), steps=3)
    with pytest.raises(InputError, match=message):
        names = tuple(name.split(","))
        solve_figures(mech, names, np.ones((1, len(names))), "c")


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_solve_many_gives_each_variants_own_trajectory_in_bounded_chunks(backend):
    study = api.prepare(api.example("slider_crank"), backend, steps=STEPS)
    base = np.array([[0.3, 4.0], [0.05, 5.0], [0.4, 7.0]])
    chunks = list(study.solve_many(base, ("L_rod", "n"), chunk=2))
    assert [len(c) for c in chunks] == [2, 1]
    for row, results in zip(base, [r for c in chunks for r in c]):
        own = own_solve("slider_crank", backend, ("L_rod", "n"), row)
        assert results.columns == own.columns and results.data.shape == own.data.shape
        assert (results.error is None) == (own.error is None)
        # a variant and its own solve: the same arithmetic, rounding
        np.testing.assert_allclose(results.data, own.data, rtol=1e-12, atol=1e-12 * np.abs(own.data).max())
        assert results.summary()[-1] == own.summary()[-1]  # the summary reads this variant's f(t)


def test_a_variant_the_c_loop_cannot_vouch_for_ends_as_its_own_solve_ends():
    # a rod a hair longer than the crank passes a toggle position at a
    # quarter turn: the compiled loop flags that step (UNEXPLAINED, 4) and
    # symid decides it in sub-steps, as `symid solve` does
    from symid.study import batch_c
    from symid.study.variants import base_matrix, study_mechanism

    mech = api.load_mechanism(api.example("slider_crank"), steps=STEPS)
    base = np.array([[0.1000001], [0.3]])
    flagged = batch_c.run(study_mechanism(mech), base_matrix(study_mechanism(mech), ("L_rod",), base), 1)
    assert list(flagged.status) == [4, 0]
    figures = solve_figures(mech, ("L_rod",), base, "c")
    for k in range(2):
        results = own_solve("slider_crank", "c", ("L_rod",), base[k])
        want, state = own_figures(mech, results)
        assert STATUS[figures.status[k]] == ("jump" if k == 0 else "ok") and state == ("failed" if k == 0 else "ok")
        assert figures.t_end[k] == results.data[-1, 0]
        assert_close(figures.values[k], want)
