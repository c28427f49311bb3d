"""The quick tier's share of a test parametrized over two dimensions (mechanisms
by backends, examples by precisions): the diagonal. Each row meets one column
in the quick tier, the columns taken in turn, so every row and every column is
run there at least once; the other pairs are in the slow tier, where the whole
product runs."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

REASON = "slow: the rest of a product the quick tier runs on its diagonal (tests/helpers/tiers.py)"


def diagonal(rows: Sequence[object], columns: Sequence[object]) -> list:
    """pytest.param(row, column) for every pair: (rows[k], columns[k mod n]) and, with
    fewer rows than columns, (rows[m mod r], columns[m]) in the quick tier, every
    other pair marked slow. Ids are `row-column`."""
    out = []
    for k, row in enumerate(rows):
        for m, column in enumerate(columns):
            quick = m == k % len(columns) or k == m % len(rows)  # row k's column, and column m's row
            out.append(pytest.param(row, column, id=f"{row}-{column}", marks=() if quick else pytest.mark.slow))
    return out


def first_quick(cases: Sequence[object], keep: int = 1, ids: Sequence[str] | None = None) -> list:
    """The first `keep` cases in the quick tier, the others slow (a breadth of
    cases through one code path: the quick tier runs that path once). A tuple
    case gives several arguments."""
    return [pytest.param(*(case if isinstance(case, tuple) else (case,)),
                         id=ids[k] if ids else str(case), marks=() if k < keep else pytest.mark.slow)
            for k, case in enumerate(cases)]
