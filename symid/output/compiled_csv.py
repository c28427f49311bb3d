"""CSV text at solver speed: a compiled '%.17g' formatter, byte for byte Python's text.

`templates/c/csv_format.c.j2` (the method of `symid.output.digits`, in C) is
rendered with its power-of-ten tables, compiled once into the solver cache
(`symid.codegen.cache.cached_entry`: a private, checked entry, loaded only
after its sha256 matches what was built) and called through ctypes, which
releases the GIL, so blocks of rows format on every core at once. A value
the C code cannot vouch for (rare: within 1e-9 of a rounding decision below
~1e-13 or above 2^64, next to a power of ten, or a non-integer outside
[1e-250, 1e250]) stops the call and is written with Python's own '%'. Without a C compiler (or when the build or the cache
fails) `csv_block` is `symid.output.digits.csv_block`: the same bytes, slower
(as for a small table before the formatter was ever built: `formatter`).
"""

from __future__ import annotations

import ctypes
import hashlib
import threading
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from symid.backends import Array
from symid.errors import InputError

TEMPLATE = "c/csv_format.c.j2"
LIBRARY = "csv_format.so"
S0, COUNT = -260, 540  # the powers 10^s, s in [S0, S0 + COUNT), the C code may look up
WIDEST = 25  # bytes of one value's text and its separator: "-1.2345678901234567e-308,"
ROOM = 64  # bytes the C code may write past the text (fixed-size copies, at most 34 from a value's start)
BUILD_AT = 500_000  # values of a table worth building the formatter for: NumPy's take ~0.5 s, gcc ~0.3 s

_lock = threading.Lock()


def render() -> str:
    """The C source, its tables of 10^s = hi + lo exact to ~2^-106 as C99 hex literals."""
    from symid.codegen.render import render as render_template
    from symid.output.digits import powers_of_ten

    hi, lo = powers_of_ten(S0, S0 + COUNT)
    return render_template(TEMPLATE, s0=S0, count=COUNT, hi=[h.hex() for h in hi], lo=[v.hex() for v in lo])


def entry() -> str:
    """The formatter's folder name in the cache: changes with symid's code and templates."""
    from symid.codegen.sources import code_version

    return "csv-format-" + hashlib.sha256(f"{TEMPLATE} {code_version()}".encode()).hexdigest()[:24]


def _make(folder: Path) -> None:
    from symid.backends.c_backend import compile_library

    source = folder / "csv_format.c"
    source.write_text(render())
    compile_library(source, folder / LIBRARY)


@cache
def library() -> Any | None:
    """The compiled formatter's `symid_csv_format`, built into the cache if needed,
    once per process; None without a compiler or when it cannot be built or loaded."""
    from symid.codegen.cache import cached_entry

    try:
        folder = cached_entry(entry(), _make, (LIBRARY,), "the CSV formatter")
        fn = ctypes.CDLL(str(folder / LIBRARY)).symid_csv_format
    except (InputError, OSError, AttributeError):  # the NumPy formatter writes the same bytes
        return None
    fn.restype = ctypes.c_long
    fn.argtypes = [ctypes.c_void_p, ctypes.c_long, ctypes.c_long, ctypes.c_long, ctypes.c_void_p,
                   ctypes.POINTER(ctypes.c_long)]
    return fn


def formatter(values: int) -> Any | None:
    """The compiled formatter for a table of `values` values so far (None: use NumPy's).

    It is built (once, into the cache) only for a table large enough to pay
    for the compiler (BUILD_AT); a smaller one uses it when the cache holds
    it already, so a short run or a sweep never waits for gcc.
    """
    from symid.codegen.cache import root

    if not library.cache_info().currsize and values < BUILD_AT and not (root() / entry()).is_dir():
        return None
    with _lock:  # one build, whichever thread asks first
        return library()


def csv_block(block: Array, fn: Any | None = None) -> bytes:
    """A block of rows (shape (rows, width)) as CSV lines: each value as
    `'%.17g' % value`, ',' between, a newline after each row.

    Args:
        fn: the compiled formatter (`formatter`); None formats with NumPy
            (`symid.output.digits.csv_block`), to the same bytes.
    """
    if fn is None:
        from symid.output.digits import csv_block as numpy_block

        return numpy_block(block)
    width = block.shape[1]
    values = np.ascontiguousarray(block, dtype=float).ravel()
    if not values.size:
        return b""
    out = np.empty(values.size * WIDEST + ROOM, np.uint8)
    at, start, stop = 0, 0, ctypes.c_long(0)
    base, data = out.ctypes.data, values.ctypes.data
    while True:
        at += fn(data, start, values.size, width, base + at, ctypes.byref(stop))
        if stop.value == values.size:
            return out[:at].tobytes()
        k = stop.value  # a value the C code cannot vouch for: Python's own text
        text = ("%.17g" % float(values[k]) + ("," if (k + 1) % width else "\n")).encode()
        out[at:at + len(text)] = np.frombuffer(text, np.uint8)
        at, start = at + len(text), k + 1
