"""Sensitivities of a new parameter value reuse what the first value built
(issue #15: parameters are inputs of the sensitivity evaluator, as of a
generated solver): no sympy derivation and no lambdify again, and the same
numbers as a fresh process."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.numeric import sensitivity_build
from symid.symbolic import sensitivity as symbolic

CRANK = api.example("slider_crank")
NAMES = ["L_crank", "m_rod", "n"]  # a length, a mass, and n through omega = 2*pi*n (time functions)
FRESH = """
import json, sys
from symid import api
r = api.solve(api.load_mechanism(sys.argv[1], {"L_crank": "0.11"}), "numpy", sensitivity=sys.argv[2], steps=5)
print(json.dumps(r.data.tolist()))
"""


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts of sympy derivations (diff, jacobian) and lambdify calls, from a cold start."""
    counts = {"diff": 0, "jacobian": 0, "lambdify": 0}

    def counting(name: str, fn):  # type: ignore[no-untyped-def]
        def wrapped(*args, **kwargs):  # type: ignore[no-untyped-def]
            counts[name] += 1
            return fn(*args, **kwargs)
        return wrapped

    monkeypatch.setattr(sp, "diff", counting("diff", sp.diff))
    monkeypatch.setattr(sp, "lambdify", counting("lambdify", sp.lambdify))
    monkeypatch.setattr(sp.MatrixBase, "jacobian", counting("jacobian", sp.MatrixBase.jacobian))
    sensitivity_build._KERNELS.clear()
    sensitivity_build._STRUCTURES.clear()
    symbolic._constraint.cache_clear()
    symbolic._force.cache_clear()
    return counts


def _solve(value: str) -> np.ndarray:
    study = api.prepare(api.load_mechanism(CRANK, {"L_crank": value}), "numpy", sensitivity=NAMES, steps=5)
    return study.solve().data


def test_a_second_parameter_value_derives_and_lambdifies_at_least_ten_times_less(counted: dict[str, int]) -> None:
    _solve("0.1")
    first = dict(counted)
    counted.update(dict.fromkeys(counted, 0))
    _solve("0.11")
    assert sum(first.values()) >= 10 * max(1, sum(counted.values())), (first, counted)
    assert counted["lambdify"] == 0 and counted["jacobian"] == 0, counted


@pytest.mark.slow  # a fresh child that derives the crank's sensitivities; the reuse counts stay in the quick tier
def test_a_reused_evaluator_gives_a_fresh_process_numbers() -> None:
    _solve("0.1")  # builds the structure at one value ...
    reused = _solve("0.11")  # ... and this run reuses it at another
    out = subprocess.run([sys.executable, "-c", FRESH, str(CRANK), ",".join(NAMES)], capture_output=True,
                         text=True, check=True)
    fresh = np.array(json.loads(out.stdout))
    assert reused.shape == fresh.shape
    scale = np.maximum(np.abs(fresh).max(axis=0), 1e-300)
    # the same evaluator with new values: the same arithmetic, rounding
    assert (np.abs(reused - fresh).max(axis=0) / scale).max() <= 1e-13
    # and the value moved the results: the reuse did not keep the first value's numbers
    assert not np.allclose(reused, _solve("0.1"))


@pytest.mark.parametrize("backend", ["numpy", "reference"])  # the backend's own loop, and the shared Python loop
def test_a_failed_run_keeps_every_instant_solved_before_it_with_its_sensitivities(backend: str) -> None:
    """Rod = crank: Phi_q is singular at t = 0.05 s; the instants before it come
    out (sensitivities are computed in chunks of instants: the last, partial
    chunk must not be lost), with the same leading columns as without."""
    mech = api.load_mechanism(CRANK, {"L_rod": "0.1"})
    plain = api.prepare(mech, backend).solve()
    sens = api.prepare(mech, backend, sensitivity=NAMES).solve()
    assert plain.error is not None and sens.error is not None
    assert sens.data.shape[0] == plain.data.shape[0] == 50
    assert np.array_equal(sens.data[:, :plain.data.shape[1]], plain.data)
    assert np.isfinite(sens.data).all()
