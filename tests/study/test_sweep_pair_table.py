"""The compiled sweep's peak joint forces taken from tables (a mechanism with
PAIR_TABLE_MIN or more constraints with reactions: a long chain, whose
written-out tests once made gcc take minutes) are the written-out form's,
bit for bit, and each is its own solve's largest |F| over the body roles."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from symid import api
from symid.codegen.c import sweep as c_sweep
from tiers import first_quick


def _sweep(name: str, monkeypatch: pytest.MonkeyPatch, cache: Path, table_min: int) -> Any:
    monkeypatch.setattr(c_sweep, "PAIR_TABLE_MIN", table_min)
    monkeypatch.setenv("SYMID_CACHE", str(cache))  # the code differs, its cache key does not
    return api.sweep(api.load_mechanism(api.example(name), steps=41), {"n": [0.5, 1.5]}, backend="c", workers=1)


# slow: two sweeps of the same grid; tests/study/test_sweep.py keeps the sweeps' tables in the quick tier
@pytest.mark.slow
@pytest.mark.parametrize("name", first_quick(["slider_crank", "quick_return", "four_bar"]))
def test_peak_forces_from_tables_are_the_written_out_ones(name: str, monkeypatch: pytest.MonkeyPatch,
                                                          tmp_path: Path) -> None:
    written = _sweep(name, monkeypatch, tmp_path / "written", 10 ** 9)
    tabled = _sweep(name, monkeypatch, tmp_path / "tabled", 0)
    assert written.columns == tabled.columns
    peaks = [c for c in written.columns if c.endswith(".force_peak")]
    assert peaks, "the example has constraints with reactions"
    assert np.array_equal(written.data, tabled.data, equal_nan=True)
    # and each is the largest |F| of its constraint's body roles over its own solve
    result = api.solve(api.load_mechanism(api.example(name), {"n": "0.5"}, steps=41), backend="reference")
    for column in peaks:
        joint = column.removesuffix(".force_peak")
        fx = [c for c in result.columns if c.startswith(joint + ".Fx_")]
        largest = max(np.max(np.hypot(result[c], result[c.replace(".Fx_", ".Fy_")])) for c in fx)
        assert tabled[column][0] == pytest.approx(largest, rel=1e-12)
