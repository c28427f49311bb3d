"""The results table as NumPy arrays (`.npz`), one array per CSV column.

Each array is named exactly as its CSV column (`t`, `crank.x`, `motor.T_j`)
and has shape (instants,); the archive keeps the columns' order.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from pathlib import Path
from typing import Iterator

import numpy as np

from symid.backends import Array
from symid.errors import AnalysisError, InputError
from symid.results import Results


def readable(path: str | Path) -> None:
    """Give a temporary file (made 0600 by mkstemp) the permissions a new file would have."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


def write_npz(path: str | Path, header: list[str], rows: Iterator[Array]) -> int:
    """Write rows as an `.npz` archive, to a temporary name renamed at the end.

    The rows are gathered in memory (an archive holds whole columns). As for
    the CSV, if the row iterator raises `AnalysisError` the rows already
    produced are written and the error re-raised; on any other error no file
    is left behind.

    Returns:
        the number of rows written.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    gathered: list[Array] = []
    failure: AnalysisError | None = None
    try:
        for values in rows:
            gathered.append(np.asarray(values, dtype=float))
    except AnalysisError as exc:
        failure = exc
    data = np.array(gathered).reshape(len(gathered), len(header))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise InputError(f"{path}: cannot write: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as out:
            # Every name but `t` holds a dot, so none collides with savez's own `file` argument.
            # (mypy matches the ** against savez's `allow_pickle: bool`, which no name here is.)
            np.savez(out, **{name: data[:, k] for k, name in enumerate(header)})  # type: ignore[arg-type]
        readable(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
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
