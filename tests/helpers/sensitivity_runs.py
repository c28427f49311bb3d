"""Sensitivity runs of a bundled example that more than one test checks, each
against its own truth (tests/numeric/test_sensitivity.py against Richardson
differences, tests/model/test_expression_elements.py against 40-digit
differences at one instant): solved once per test run, by whichever worker asks
first (tests/helpers/runshare.py), not once per test. The derivation of every
base parameter's columns is the costly part (seconds on the reference backend,
a C build on the c backend)."""

from __future__ import annotations

from typing import Sequence

import pytest

from runshare import key_of, shared_value
from symid import api


def solved(factory: pytest.TempPathFactory, example: str, backend: str, names: Sequence[str],
           steps: int) -> api.Results:
    """`symid solve EXAMPLE --backend BACKEND --sensitivity NAMES --steps STEPS`
    (the default columns: the drivers' efforts and the reactions)."""
    path = api.example(example)
    key = key_of("sensitivity_runs.solved", example, path, backend, tuple(names), steps)
    return shared_value(factory, key, lambda: api.solve(path, backend, sensitivity=list(names), steps=steps))
