"""Tables written at the solver's pace: CSV, .npz and Parquet from blocks of rows.

Every writer takes an iterable of rows (1-D) or blocks of rows (2-D, the
compiled loop's chunks) and writes them through `symid.io.files`, so a file
is complete or untouched. If the iterable raises `AnalysisError`, the rows
before it are written, the file completed, and the error re-raised; on any
other error nothing is left behind. `write_table` is the one entry point for
a (names, array or blocks) table by its file's suffix.
"""

from __future__ import annotations

import os
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import IO, Any, Iterable, Iterator

import numpy as np

from symid.backends import Array
from symid.errors import AnalysisError, InputError
from symid.io.files import atomic_write, check_target, output_format

BLOCK = 1024  # rows gathered before formatting: ~70k values, a few MB of text at most
GROUP = 65536  # rows of one Parquet row group
SUFFIXES = (".csv", ".npz", ".parquet")


def blocks(items: Iterable[Array], width: int, size: int = BLOCK) -> Iterator[Array]:
    """2-D float blocks of `width` columns from rows, blocks, or a mix.

    Rows are gathered into blocks of up to `size`; blocks pass through (cut
    to `size` rows, so a whole table is formatted a block at a time). An
    `AnalysisError` from `items` comes after the rows gathered before it.
    """
    pending = np.empty((size, width))
    count = 0
    try:
        for item in items:
            values = np.asarray(item, dtype=float)
            if values.ndim == 2:
                if count:
                    yield pending[:count].copy()
                    count = 0
                values = values.reshape(-1, width)
                for start in range(0, values.shape[0], size):  # a whole table comes in blocks too
                    yield values[start:start + size]
                continue
            pending[count] = values
            count += 1
            if count == size:
                yield pending.copy()
                count = 0
    except AnalysisError:
        if count:
            yield pending[:count].copy()
        raise
    if count:
        yield pending[:count].copy()


def write_csv(path: str | Path, header: list[str], rows: Iterable[Array]) -> int:
    """The table as CSV: '%.17g' values (`symid.output.compiled_csv`), ',' between,
    a header line of the names; returns the rows written.

    Blocks are formatted on every core (up to WORKERS) while the next block
    is solved and the oldest one written, in order (the compiled formatter
    and NumPy's loops release the GIL); at most AHEAD blocks per core wait,
    so memory stays bounded by a few blocks (~4 MB each with their text).
    The first block is written as soon as it is formatted, later ones as soon
    as they are formatted and next in order.
    """
    from symid.output.compiled_csv import csv_block, formatter

    count = seen = 0
    failure: AnalysisError | None = None
    workers = min(WORKERS, os.cpu_count() or 1)
    pool = ThreadPoolExecutor(max_workers=workers)
    waiting: deque[tuple[Future[bytes], int]] = deque()
    try:
        with atomic_write(path, binary=True) as out:
            out.write((",".join(header) + "\n").encode())
            try:
                for block in blocks(rows, len(header)):
                    seen += block.size
                    waiting.append((pool.submit(csv_block, block, formatter(seen)), len(block)))
                    # the first block, and any formatted one next in line, is written at once: a slow
                    # loop's rows reach the file a block after they are solved, not AHEAD blocks later
                    while waiting and (not count or len(waiting) > AHEAD * workers or waiting[0][0].done()):
                        count += _drain(waiting, out)
            except AnalysisError as exc:  # keep the instants before it: the file is completed
                failure = exc
            while waiting:
                count += _drain(waiting, out)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    if failure is not None:
        raise failure
    return count


AHEAD = 2  # formatted blocks in flight per core
WORKERS = 8  # cores formatting at most: 8 format ~2 GB/s of text, more than a disk takes


def _drain(waiting: deque[tuple[Future[bytes], int]], out: IO[bytes]) -> int:
    """Write the oldest block's text; returns its rows."""
    future, rows = waiting.popleft()
    out.write(future.result())
    return rows


def arrow() -> Any:
    """pyarrow and pyarrow.parquet, or one line saying how to get them (exit 2)."""
    try:
        import pyarrow
        import pyarrow.parquet as pq
    except ImportError:
        raise InputError("writing .parquet needs pyarrow (python3 -m pip install 'symid[study]' or pyarrow); "
                         "use .csv or .npz without it") from None
    return pyarrow, pq


def write_parquet(path: str | Path, header: list[str], rows: Iterable[Array]) -> int:
    """The table as Parquet: one float64 column per name, row groups of GROUP rows."""
    pa, pq = arrow()
    check_target(path)
    schema = pa.schema([(name, pa.float64()) for name in header])
    count = 0
    failure: AnalysisError | None = None
    with atomic_write(path, binary=True) as out:
        with pq.ParquetWriter(out, schema) as writer:
            gathered: list[Array] = []
            held = 0
            try:
                for block in blocks(rows, len(header)):
                    gathered.append(block)
                    held += len(block)
                    if held >= GROUP:
                        _group(writer, pa, schema, gathered)
                        count, gathered, held = count + held, [], 0
            except AnalysisError as exc:
                failure = exc
            _group(writer, pa, schema, gathered)
            count += held
    if failure is not None:
        raise failure
    return count


def _group(writer: Any, pa: Any, schema: Any, gathered: list[Array]) -> None:
    """Write the gathered blocks as one row group (none: an empty table keeps its schema)."""
    data = np.concatenate(gathered) if gathered else np.empty((0, len(schema)))
    writer.write_table(pa.Table.from_arrays([pa.array(np.ascontiguousarray(data[:, k]))
                                             for k in range(data.shape[1])], schema=schema))


def read_arrow(path: str | Path) -> Any:
    """The pyarrow table of a Parquet file; one line (InputError) when it cannot be read."""
    _, pq = arrow()
    try:
        return pq.read_table(path)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read as .parquet: {exc}") from None


def read_parquet(path: str | Path) -> tuple[list[str], Array]:
    """(names, data of shape (rows, names)) of a Parquet table of float columns."""
    table = read_arrow(path)
    names = list(table.column_names)
    data = np.empty((table.num_rows, len(names)))
    for k, name in enumerate(names):
        data[:, k] = table.column(name).to_numpy()
    return names, data


def write_table(path: str | Path, names: list[str], data: Array | Iterable[Array],
                total: int | None = None) -> int:
    """Write a table by its suffix (.csv, .npz, .parquet; any other refused), atomically.

    Args:
        names: the column names.
        data: a 2-D array (rows, names), or an iterable of rows or 2-D blocks.
        total: the rows expected, if known (lets .npz preallocate its columns).

    Returns:
        the number of rows written.
    """
    from symid.output.npz import write_npz

    suffix = output_format(path, SUFFIXES, "a results table")
    if isinstance(data, np.ndarray):
        total = data.shape[0] if total is None else total
        data = [data.reshape(-1, len(names))]
    if suffix == ".npz":
        return write_npz(path, names, data, total)
    if suffix == ".parquet":
        return write_parquet(path, names, data)
    return write_csv(path, names, data)
