"""The gradient of every study figure against central differences of the
figure itself, on examples with each kind of driver effort (a motor torque
column, a distance driver's -2|f| lambda, a translational driver's -lambda)
and a driver rate that moves with a parameter (the slider-crank's n)."""

from __future__ import annotations

import math

import pytest

from symid import api
from symid.model.mechanism import parameter_symbol
from symid.model.params import parameter_values
from symid.output.results import columns
from symid.study.figures import figure_names
from symid.study.gradients import figure_gradients, gradient_names, has_gradient, needed_columns
from symid.study.slow import figures_of, solve_variant, study_analysis, with_values
from symid.symbolic.assemble import assemble
from symid.tools.sensitive import solver

CASES = {  # example: (base parameters, steps)
    "slider_crank": (("L_rod", "m_slider", "n"), 21),
    "slider_crank_counterweight": (("m_cw", "beta_cw"), 41),
    "slider_crank_sized": (("L_rod", "n"), 21),  # the drive's motor_rms and motor_peak too
    "excavator": (("a_stick", "T_cycle"), 11),
    "slider_pendulum": (("s_amp",), 11),
}


def provider():
    """The exact sensitivities (`api.prepare(..., sensitivity=...)`), on numpy."""
    return solver("numpy")


def mechanism(example: str, steps: int):
    return study_analysis(api.load_mechanism(api.example(example), steps=steps))


@pytest.mark.parametrize("example", sorted(CASES))
def test_each_figure_gradient_matches_central_differences_of_the_figure(example):
    names, steps = CASES[example]
    mech = mechanism(example, steps)
    missing = [n for n in names if parameter_symbol(n) not in parameter_values(mech.parameters)]
    assert not missing, f"{example} has no parameters {missing}"
    header = columns(assemble(mech), mech.analysis)
    results = provider()(mech, names, needed_columns(mech, header))
    assert results.error is None
    grads = figure_gradients(mech, results, names)
    figures = figure_names(mech)
    values = parameter_values(mech.parameters)
    own = figures_of(mech, results)  # the figures of the run itself, for each gradient's scale
    for j, name in enumerate(names):
        p = values[parameter_symbol(name)]
        h = 1e-5 * max(abs(p), 1e-2)
        up, down = with_values(mech, [name], [p + h]), with_values(mech, [name], [p - h])
        central = (figures_of(up, solve_variant(up, "numpy")) - figures_of(down, solve_variant(down, "numpy"))) / (2 * h)
        for i, figure in enumerate(figures):
            if not has_gradient(figure):
                assert math.isnan(grads[i, j]), figure
                continue
            scale = max(abs(own[i]) / max(abs(p), 1e-2), 1e-9)
            assert grads[i, j] == pytest.approx(central[i], abs=1e-5 * scale, rel=1e-5), \
                f"{example}: d({figure})/d({name})"


def test_gradient_names_are_figures_outer_parameters_inner():
    assert gradient_names(["a.effort_rms", "b.force_peak"], ["x", "y"]) == [
        "d(a.effort_rms)/d(x)", "d(a.effort_rms)/d(y)", "d(b.force_peak)/d(x)", "d(b.force_peak)/d(y)"]
