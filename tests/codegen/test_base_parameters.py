"""Base and derived parameters (contract v1.1): generated code takes the base
parameters only and computes the derived ones from them by their definitions."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api
from symid.errors import InputError
from symid.model.params import base_names

SLIDER_CRANK = api.example("slider_crank")  # omega = "2*pi*n" is derived
STEPS = 21


def scaled_error(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| relative to each column's magnitude (columns of zeros: absolute)."""
    scale = np.maximum(np.abs(b).max(axis=0), 1.0)
    return float(np.max(np.abs(a - b) / scale))


@pytest.mark.parametrize("backend", ["c", "numpy", "casadi"])
def test_changing_a_base_parameter_in_p_changes_the_derived_one_as_set_does(backend):
    study = api.prepare(SLIDER_CRANK, backend, steps=STEPS)
    names = base_names(study.mechanism.parameters)
    p = study.evaluator.p  # type: ignore[attr-defined]
    assert len(p) == len(names) and "omega" not in names  # the generated code's p holds base parameters only
    default = study.solve().data.copy()
    p[names.index("n")] = 7.0  # in the generated code's own parameter vector
    if hasattr(study.evaluator, "p_list"):  # the NumPy backend's scalar kernels take p as a list
        study.evaluator.p_list = p.tolist()
    changed = study.solve().data
    truth = api.prepare(SLIDER_CRANK, "reference", set_values={"n": "7"}, steps=STEPS).solve().data
    # the derived parameter recomputed in the solver against the file's: rounding of a tol 1e-12 solve
    assert scaled_error(changed, truth) < 1e-12
    assert scaled_error(default, truth) > 1e-3  # a stale omega would have left the motion at n = 5


def test_generated_headers_say_which_parameters_are_inputs(tmp_path):
    api.generate(SLIDER_CRANK, "c", tmp_path / "c")
    header = (tmp_path / "c" / "slider_crank_solver.h").read_text()
    assert "the base parameters, the only inputs" in header and "omega = 2*pi*n" in header
    assert "#define SLIDER_CRANK_NP 9 " in header  # 10 parameters, omega derived
    api.generate(SLIDER_CRANK, "casadi", tmp_path / "casadi")
    readme = (tmp_path / "casadi" / "README.txt").read_text()
    assert "omega = 2*pi*n" in readme and "p[7] n = 5.0" in readme and "] omega =" not in readme


def test_set_values_of_a_derived_parameter_is_an_input_error_naming_its_definition():
    with pytest.raises(InputError, match=r"--set omega: 'omega' is a derived parameter \(omega = \"2\*pi\*n\""):
        api.prepare(SLIDER_CRANK, "reference", set_values={"omega": "3"})
