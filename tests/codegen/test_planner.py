"""The heap-driven pivot planner chooses exactly the pivots (and so the fill,
slots and generated code) of the rescanning planner it replaced."""

from __future__ import annotations

import numpy as np
import pytest

from symid.codegen import sparse
from planner_reference import rescanning_plan


def _pattern(rng: np.random.Generator, n: int, density: float, diagonal: bool) -> list[tuple[int, int]]:
    mask = rng.random((n, n)) < density
    if diagonal:
        mask |= np.eye(n, dtype=bool)
    cells = [(int(r), int(c)) for r, c in zip(*np.nonzero(mask))]
    order = rng.permutation(len(cells))
    return [cells[k] for k in order]


@pytest.mark.parametrize("seed", range(12))
def test_heap_planner_matches_rescanning_planner_on_random_patterns(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 40))
    pattern = _pattern(rng, n, float(rng.uniform(0.03, 0.3)), diagonal=seed % 3 != 0)
    sample = np.zeros((n, n))
    # small integers make ties in cost and in |entry| / column max; zeros force
    # the structural fallback for some columns
    values = rng.integers(-3, 4, len(pattern)).astype(float) if seed % 2 else rng.normal(size=len(pattern))
    for (r, c), v in zip(pattern, values):
        sample[r, c] = v
    old = rescanning_plan(pattern, sample)
    assert sparse.plan(pattern, sample) == old
    assert sparse.plan(pattern, [sample[r, c] for r, c in pattern], n) == old


def test_heap_planner_matches_rescanning_planner_on_a_banded_chain() -> None:
    """A ladder-like pattern: blocks of 3 coupled to their neighbours, the
    structure whose plan the generated code of long chains follows."""
    rng = np.random.default_rng(7)
    n = 60
    pattern = sorted({(r, c) for r in range(n) for c in range(max(0, r - 4), min(n, r + 5))
                      if (r + c) % 2 == 0 or abs(r - c) < 2})
    sample = np.zeros((n, n))
    for r, c in pattern:
        sample[r, c] = float(rng.choice([-1.0, 1.0, 0.5 * rng.normal()]))
    assert sparse.plan(pattern, sample) == rescanning_plan(pattern, sample)
