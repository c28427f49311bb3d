"""The Python loop's scales (`Scaling`) from Phi_q's entries, for large
mechanisms: a dense Phi_q of the ladder of 1024 is 302 MB. No sympy here (a
cached run loads a built solver without it)."""

from __future__ import annotations

import numpy as np

from symid.numeric.stability import Scaling, _power_of_two, reference_length

Array = np.ndarray


def scaling_of_entries(rows: Array, cols: Array, values: Array, q: Array, nc: int) -> Scaling:
    """`Scaling.of` from Phi_q's entries (nothing nc x ng): the same scales
    as the dense matrix gives, entry for entry."""
    ng = q.size
    rows, cols = np.asarray(rows, dtype=np.intp), np.asarray(cols, dtype=np.intp)
    mag = np.abs(np.asarray(values, dtype=float))
    rot = cols % 3 == 2
    lin_part, rot_part = np.zeros(nc), np.zeros(nc)
    np.maximum.at(lin_part, rows[~rot], mag[~rot])
    np.maximum.at(rot_part, rows[rot], mag[rot])
    mixed = (lin_part > 0) & (rot_part > 0)
    lref = reference_length(rot_part[mixed] / lin_part[mixed])
    qrot = np.arange(ng) % 3 == 2
    if not lref > 0:
        lref = float(np.max(np.abs(q[~qrot]), initial=0.0))
    if not lref > 0 or not np.isfinite(lref):
        lref = 1.0
    col = np.where(qrot, 1.0, lref)
    row = np.zeros(nc)
    np.maximum.at(row, rows, mag * col[cols])
    row = np.where((row > 0) & np.isfinite(row), row, 1.0)
    return Scaling(lref, col, row, _power_of_two(col), 1.0 / _power_of_two(row), 1.0 / col, 1.0 / row)
