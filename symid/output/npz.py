"""The results table as NumPy arrays (`.npz`), one array per CSV column.

Each array is named exactly as its CSV column (`t`, `crank.x`, `motor.T_j`)
and has shape (instants,); the archive keeps the columns' order.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from pathlib import Path
from typing import IO, Iterable

import numpy as np

from symid.backends import Array
from symid.errors import AnalysisError, InputError
from symid.io.files import atomic_write, cannot_write, check_target
from symid.output.results import Results


def write_npz(path: str | Path, header: list[str], rows: Iterable[Array], total: int | None = None) -> int:
    """Write rows (or 2-D blocks of rows) as an `.npz` archive through
    `symid.io.files.atomic_write`, holding one block in memory at a time.

    Each block's columns go into a column-major scratch file beside `path`
    (preallocated for `total` rows, unlinked at once so nothing outlives the
    run); at the end each column is copied into the archive as an array. As
    for the CSV, if the rows raise `AnalysisError` the rows already produced
    are written and the error re-raised; on any other error no file is left.

    Returns:
        the number of rows written.
    """
    from symid.output.tables import blocks

    check_target(path)  # before the run, not after it
    width = len(header)
    failure: AnalysisError | None = None
    try:
        scratch = tempfile.TemporaryFile(prefix=f".{Path(path).name}.", dir=Path(path).parent)
    except OSError:  # a folder that takes no new file (a FIFO's, /dev): the system's temporary folder
        try:
            scratch = tempfile.TemporaryFile(prefix=".symid-npz.")
        except OSError as exc:
            raise cannot_write(path, exc) from None
    with scratch:
        try:
            store = _Columns(scratch.fileno(), width, max(total or 0, 1))  # sized up front: EFBIG here
            try:
                for block in blocks(rows, width):
                    store.add(block)
            except AnalysisError as exc:
                failure = exc
        except OSError as exc:
            raise cannot_write(path, exc) from None
        with atomic_write(path, binary=True) as out:
            with zipfile.ZipFile(out, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
                for k, name in enumerate(header):
                    # Every name but `t` holds a dot: none collides with another member.
                    with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                        np.lib.format.write_array_header_1_0(
                            member, {"descr": "<f8", "fortran_order": False, "shape": (store.count,)})
                        store.copy_column(k, member)
    if failure is not None:
        raise failure
    return store.count


class _Columns:
    """Columns of float64 in a file, column k at k * capacity values, grown by doubling."""

    PIECE = 1 << 20  # bytes copied at once

    def __init__(self, fd: int, width: int, capacity: int) -> None:
        self.fd, self.width, self.capacity, self.count = fd, width, capacity, 0
        os.ftruncate(fd, 8 * width * capacity)

    def add(self, block: Array) -> None:
        """Append a block of rows (shape (rows, width))."""
        rows = block.shape[0]
        if self.count + rows > self.capacity:
            self._grow(max(2 * self.capacity, self.count + rows))
        data = np.asarray(block, dtype="<f8")
        for k in range(self.width):
            os.pwrite(self.fd, np.ascontiguousarray(data[:, k]).tobytes(), 8 * (k * self.capacity + self.count))
        self.count += rows

    def _grow(self, capacity: int) -> None:
        """Move the columns apart, last first (the new places never overlap an unmoved one)."""
        os.ftruncate(self.fd, 8 * self.width * capacity)
        for k in range(self.width - 1, 0, -1):
            for start in range(self.count * 8 - 1 - (self.count * 8 - 1) % self.PIECE, -1, -self.PIECE):
                end = min(start + self.PIECE, 8 * self.count)
                data = os.pread(self.fd, end - start, 8 * k * self.capacity + start)
                os.pwrite(self.fd, data, 8 * k * capacity + start)
        self.capacity = capacity

    def copy_column(self, k: int, out: IO[bytes]) -> None:
        """Write column k's values (count of them) to out."""
        base, size = 8 * k * self.capacity, 8 * self.count
        for start in range(0, size, self.PIECE):
            out.write(os.pread(self.fd, min(self.PIECE, size - start), base + start))


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
