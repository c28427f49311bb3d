"""How two results tables are compared: shared by the backend-agreement tests."""

from __future__ import annotations

import numpy as np


def assert_agree(got: np.ndarray, expected: np.ndarray, rel: float = 1e-12) -> None:
    """Per column, relative to the column's peak; columns that are zero up to
    rounding are measured against the table's largest value instead."""
    assert got.shape == expected.shape
    col = np.max(np.abs(expected), axis=0)
    scale = np.maximum(col, 1e-3 * np.max(col))
    worst = np.max(np.abs(got - expected) / scale)
    assert worst <= rel, worst
