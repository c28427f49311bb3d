"""`symid optimize` against independent truth: a dense grid of the same
figure, scipy's own finite-difference gradients, and its command line (the
snippet written, exit 3 when it does not converge or visits a variant that
does not solve)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.study import design
from symid.study import optimize as opt
from symid.tools.sensitive import solver as exact

EXAMPLE = api.example("slider_crank_counterweight")
STEPS = 11
VARY = ["m_cw=1:4", "beta_cw=2.5:3.8"]


def solver():
    return exact("numpy")


@pytest.fixture(scope="module")
def optimum() -> opt.Outcome:
    mech = api.load_mechanism(EXAMPLE, steps=STEPS)
    return opt.run(opt.Problem(mech, "motor.effort_rms", opt.parse_vary(VARY), [], solver()))


def test_optimum_is_at_least_as_good_as_a_dense_grid_and_near_its_best_point(optimum):
    assert optimum.success, optimum.message
    mech = api.load_mechanism(EXAMPLE, steps=STEPS)
    grid = design.grid(["m_cw=1:4:31", "beta_cw=2.5:3.8:27"])
    table = api.sweep(mech, grid, backend="numpy")
    rms = table["motor.effort_rms"]
    best = int(np.argmin(rms))
    assert optimum.value <= rms[best] * (1 + 1e-12)
    spacing = np.array([0.1, 0.05])
    assert np.all(np.abs(optimum.p - grid.values[best]) <= spacing), (optimum.p, grid.values[best])
    assert optimum.value < 0.5 * optimum.start_value  # the counterweight carries the piston's weight


def test_finite_difference_gradients_reach_the_same_optimum_in_more_solves(optimum):
    mech = api.load_mechanism(EXAMPLE, steps=STEPS)
    plain = opt.run(opt.Problem(mech, "motor.effort_rms", opt.parse_vary(VARY), [], solver(), exact=False))
    assert plain.success, plain.message
    assert plain.value == pytest.approx(optimum.value, rel=1e-8)
    assert plain.p == pytest.approx(optimum.p, rel=1e-6)
    assert optimum.evaluations < plain.evaluations


def test_a_limit_on_another_figure_is_kept(optimum):
    """Bound the crank pin's peak force below its value at the free optimum: the
    constrained optimum keeps the bound (active) and pays for it in RMS torque."""
    mech = api.load_mechanism(EXAMPLE, steps=STEPS)
    free = opt.Problem(mech, "motor.effort_rms", opt.parse_vary(VARY), [], solver())
    u = (optimum.p - free.lo) / free.width
    force = free.value(u, "main_bearing.force_peak")
    limit = opt.Limit("main_bearing.force_peak", "<=", 0.97 * force)
    problem = opt.Problem(mech, "motor.effort_rms", opt.parse_vary(VARY), [limit], solver())
    out = opt.run(problem)
    assert out.success, out.message
    reached = problem.value((out.p - problem.lo) / problem.width, limit.figure)
    assert reached <= limit.value * (1 + 1e-6)
    assert reached == pytest.approx(limit.value, rel=1e-4)  # active
    assert out.value > optimum.value


@pytest.fixture()
def cli(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)

    def run(*args: str) -> int:
        return main(["optimize", str(EXAMPLE), "--steps", str(STEPS), *args])

    return run


@pytest.mark.slow  # an optimization from the command line; the optimizer's API tests stay in the quick tier
def test_cli_prints_iterations_and_writes_the_optimum_as_a_parameters_snippet(cli, capsys, optimum):
    args = ["--minimize", "motor.effort_rms"] + [a for v in VARY for a in ("--vary", v)]
    assert cli(*args) == 0
    out = capsys.readouterr().out
    assert "iteration 1: motor.effort_rms = " in out and "|gradient| = " in out
    assert "optimum: m_cw = " in out
    snippet = tomllib.loads(Path("slider_crank_counterweight_optimized.toml").read_text())
    assert list(snippet["parameters"]) == ["m_cw", "beta_cw"]
    assert [snippet["parameters"]["m_cw"], snippet["parameters"]["beta_cw"]] == pytest.approx(optimum.p, rel=1e-9)


def test_an_optimum_on_a_bound_is_said_to_be_there(cli, capsys, optimum):
    """m_cw's range cut below its free optimum (an interior point, the dense
    grid above says): the optimum holds the upper bound, and the line and the
    snippet say so; beta_cw stays inside and says nothing."""
    assert optimum.bound == ("", "") and "bound" not in optimum.where()
    top = round(float(optimum.p[0]) - 0.1, 6)
    assert cli("--minimize", "motor.effort_rms", "--vary", f"m_cw=1:{top}", "--vary", VARY[1]) == 0
    out = capsys.readouterr().out
    assert f"optimum: m_cw = {top:.10g} (on its upper bound), beta_cw = " in out
    assert "beta_cw = " in out and out.count("bound") == 1
    text = Path("slider_crank_counterweight_optimized.toml").read_text()
    assert f"m_cw = {top!r}  # on its upper bound" in text
    assert tomllib.loads(text)["parameters"]["m_cw"] == top


def test_cli_exit_3_with_the_optimizers_message_when_it_does_not_converge(cli, capsys):
    status = cli("--minimize", "motor.effort_rms", "--vary", "m_cw=1:4", "--vary", "beta_cw=2.5:3.8",
                 "--maxiter", "1", "-o", "best.toml")
    err = capsys.readouterr().err
    assert status == 3, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "the optimizer did not converge after 1 iterations" in err and "Iteration limit" in err
    assert not Path("best.toml").exists()


def test_cli_reports_a_variant_that_does_not_assemble(cli, capsys):
    """A crank longer than the rod cannot turn: the visited variant is named with
    the figure over the instants before, the time and the reason; exit 3."""
    status = cli("--minimize", "motor.effort_rms", "--vary", "L_crank=0.05:0.5", "--set", "L_crank=0.35",
                 "-o", "best.toml")
    err = capsys.readouterr().err
    assert status == 3, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "the optimizer visited L_crank = 0.34999999999999998 (the start), which does not solve: motor.effort_rms = " in err
    assert "over the instants before t = " in err
    assert not Path("best.toml").exists()
