"""The results table as NumPy arrays (`.npz`), one array per CSV column.

Each array is named exactly as its CSV column (`t`, `crank.x`, `motor.T_j`)
and has shape (instants,); the archive keeps the columns' order.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Iterator

import numpy as np

from symid.backends import Array
from symid.errors import AnalysisError, InputError
from symid.io.files import atomic_write, check_target
from symid.output.results import Results


def write_npz(path: str | Path, header: list[str], rows: Iterator[Array]) -> int:
    """Write rows as an `.npz` archive through `symid.io.files.atomic_write`.

    The rows are gathered in memory (an archive holds whole columns). As for
    the CSV, if the row iterator raises `AnalysisError` the rows already
    produced are written and the error re-raised; on any other error no file
    is left behind.

    Returns:
        the number of rows written.
    """
    check_target(path)  # before the run, not after it
    gathered: list[Array] = []
    failure: AnalysisError | None = None
    try:
        for values in rows:
            gathered.append(np.asarray(values, dtype=float))
    except AnalysisError as exc:
        failure = exc
    data = np.array(gathered).reshape(len(gathered), len(header))
    with atomic_write(path, binary=True) as out:
        # Every name but `t` holds a dot, so none collides with savez's own `file` argument.
        # (mypy matches the ** against savez's `allow_pickle: bool`, which no name here is.)
        np.savez(out, **{name: data[:, k] for k, name in enumerate(header)})  # type: ignore[arg-type]
    if failure is not None:
        raise failure
    return len(gathered)


def read_npz(path: str | Path) -> Results:
    """Read an archive written by `write_npz` back as a `Results` table."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as archive:
            header = list(archive.files)
            columns = [np.asarray(archive[name], dtype=float) for name in header]
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise InputError(f"{path}: cannot read as .npz: {exc}") from None
    if not header or header[0] != "t" or any(c.shape != columns[0].shape or c.ndim != 1 for c in columns):
        raise InputError(f"{path}: not a symid results archive (first array 't', all of one length)")
    data = np.stack(columns, axis=1)
    return Results(header, data)
