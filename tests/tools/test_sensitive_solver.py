"""The optimizer's solver (`symid.tools.sensitive.solver`) prepares a study
once and reuses it for every variant that differs in base parameter values
only: each variant's run must be the one a fresh `api.prepare` gives."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.model.mechanism import parameter_symbol
from symid.model.params import parameter_values
from symid.study.slow import study_analysis, with_values
from symid.tools.sensitive import solver
from tiers import diagonal

STEPS = 21


@pytest.mark.parametrize("names, backend", diagonal([("L_rod", "n"), ()], ["c", "numpy"]))
def test_a_reused_study_solves_each_variant_as_a_fresh_one_does(backend, names):
    mech = study_analysis(api.load_mechanism(api.example("slider_crank"), steps=STEPS))
    columns = ["motor.T_j"] if names else []
    solve = solver(backend)
    for values in ([0.3, 4.0], [0.42, 7.5], [0.25, 2.0]):  # the 2nd and 3rd reuse the 1st's study
        variant = with_values(mech, ("L_rod", "n"), values)
        own = solve(variant, names, columns)
        fresh = api.prepare(variant, backend=backend, sensitivity=list(names) or None,
                            sensitivity_of=columns or None).solve()
        assert own.columns == fresh.columns and own.error is None
        assert own.mechanism is variant
        np.testing.assert_array_equal(own.data, fresh.data)


def test_a_variant_of_another_structure_is_prepared_anew():
    """Another analysis (here: more instants) is no longer the same solver's variant."""
    mech = study_analysis(api.load_mechanism(api.example("slider_crank"), steps=STEPS))
    solve = solver("c")
    assert len(solve(mech, (), []).t) == STEPS
    longer = study_analysis(api.load_mechanism(api.example("slider_crank"), steps=STEPS + 4))
    assert len(solve(longer, (), []).t) == STEPS + 4


def test_parameter_values_follow_a_dictionary_changed_in_place():
    """parameter_values remembers its latest answer by content, never by identity."""
    params = {"a": sp.Float(1.0), "b": 2 * parameter_symbol("a")}
    b = parameter_symbol("b")
    assert parameter_values(params)[b] == 2.0
    params["a"] = sp.Float(3.0)
    assert parameter_values(params)[b] == 6.0
    parameter_values(params)[b] = -1.0  # a caller's change to its copy stays its own
    assert parameter_values(params)[b] == 6.0
