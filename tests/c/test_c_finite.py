"""The generated C's check that an instant's outputs are finite: every value
of every output group is looked at (an inf or NaN in any one slot stops the
instant), and no finite value, however large or small, is taken for one that
is not. The check runs on the product code: the generated solver with a
harness that calls its static `finite`."""

from __future__ import annotations

import ctypes
import shutil

import numpy as np
import pytest

from symid import api
from symid.codegen.model import code_model
from symid.io.reader import load
from csolver import DP, instrumented

HARNESS = """
int test_finite(const double *q, const double *qd, const double *qdd, const double *lam, const double *reac);
int test_finite(const double *q, const double *qd, const double *qdd, const double *lam, const double *reac)
{{
    return {p}_finite(q, qd, qdd, lam, reac);
}}
"""


@pytest.fixture(scope="module")
def finite(tmp_path_factory):  # type: ignore[no-untyped-def]
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    model = code_model(load(api.example("slider_crank")))
    lib, ctx, _ = instrumented(model, tmp_path_factory.mktemp("finite"), HARNESS.format(p=model.name))
    f = lib.test_finite
    f.argtypes = [DP] * 5
    f.restype = ctypes.c_int
    sizes = (ctx.ng, ctx.ng, ctx.ng, ctx.nc, ctx.nr)

    def check(values: np.ndarray) -> bool:
        parts = np.split(np.ascontiguousarray(values, dtype=float), np.cumsum(sizes)[:-1])
        return bool(f(*(p.ctypes.data_as(DP) for p in parts)))

    return check, sum(sizes)


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_c_finite_rejects_a_non_finite_value_in_any_slot(finite, bad: float) -> None:
    check, n = finite
    rng = np.random.default_rng(14)
    base = rng.standard_normal(n) * 1e3
    assert check(base)
    missed = [k for k in range(n) if check(np.where(np.arange(n) == k, bad, base))]
    assert missed == [], f"slots taken as finite while holding {bad}: {missed}"


def test_c_finite_accepts_extreme_finite_values(finite) -> None:
    check, n = finite
    extremes = np.array([np.finfo(float).max, -np.finfo(float).max, 5e-324, -0.0, 0.0])
    assert check(np.resize(extremes, n))
    assert check(np.full(n, np.finfo(float).max))  # a sum of |v| would overflow to inf here
