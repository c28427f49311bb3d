"""A study sets its solver up once: `warm` builds the very solver the chunks
run (one cache entry, not the normal path's evaluator as well), and every
chunk of the same mechanism object reuses it, loaded and checked, with the
figures of a fresh set-up."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.study import batch_c
from symid.study.engine import solve_figures
from symid.study.memo import ByIdentity
from symid.study.run import warm

NAMES = ("L_rod", "n")
BASE = np.array([[0.3, 5.0], [0.35, 6.0]])


@pytest.fixture
def loads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The mechanisms whose batch solver was loaded, one entry a load."""
    seen: list[str] = []
    original = batch_c._load

    def counting(mechanism):  # type: ignore[no-untyped-def]
        seen.append(mechanism.name)
        return original(mechanism)

    monkeypatch.setattr(batch_c, "_load", counting)
    return seen


def test_warm_builds_only_the_solver_the_chunks_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    loads: list[str]) -> None:
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path))
    mech = api.load_mechanism(api.example("slider_crank"), steps=11)
    warm(mech, "c")
    solve_figures(mech, NAMES, BASE, "c", workers=1)
    solve_figures(mech, NAMES, BASE[:1], "c", workers=1)
    assert [p.name.split("-")[0] for p in tmp_path.iterdir() if p.is_dir()] == ["c"]
    assert loads == ["slider_crank"]


def test_chunks_of_one_mechanism_reuse_its_solver_with_the_same_figures(loads: list[str]) -> None:
    mech = api.load_mechanism(api.example("slider_crank"), steps=11)
    first = solve_figures(mech, NAMES, BASE, "c", workers=2)
    again = solve_figures(mech, NAMES, BASE, "c", workers=2)
    assert loads == ["slider_crank"]
    other = api.load_mechanism(api.example("slider_crank"), steps=11)  # equal, but another object
    fresh = solve_figures(other, NAMES, BASE, "c", workers=1)
    assert loads == ["slider_crank", "slider_crank"]
    assert np.array_equal(first.values, again.values) and np.array_equal(first.values, fresh.values)
    assert np.all(first.status == 0) and np.all(np.isfinite(first.values))


def test_memo_by_identity_keys_each_object_and_key_apart() -> None:
    class Thing:
        __hash__ = None  # type: ignore[assignment]  # unhashable, as a Mechanism is

    memo: ByIdentity[int] = ByIdentity()
    a, b = Thing(), Thing()
    made: list[int] = []

    def make(v: int) -> int:
        made.append(v)
        return v

    assert memo.get(a, "c", lambda: make(1)) == 1
    assert memo.get(a, "c", lambda: make(2)) == 1
    assert memo.get(b, "c", lambda: make(3)) == 3
    assert memo.get(a, "numpy", lambda: make(4)) == 4
    assert made == [1, 3, 4]
