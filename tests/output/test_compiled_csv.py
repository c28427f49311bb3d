"""The compiled CSV formatter: Python's '%.17g' byte for byte on every kind of
double, the rows' structure, its place in the checked cache, and the NumPy
formatter's same bytes when there is no compiler (or the build fails)."""

from __future__ import annotations

import ctypes
import math
import shutil
import struct
import subprocess
import tracemalloc
from decimal import Decimal
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from symid.codegen import cache
from symid.output import compiled_csv
from symid.output.compiled_csv import BUILD_AT, csv_block, formatter, library
from symid.output.results import format_row
from symid.output.tables import write_csv
from symid.study.figures import Figures
from symid.study.table import SweepTable

HAS_CC = any(shutil.which(c) for c in ("cc", "gcc", "clang"))
needs_cc = pytest.mark.skipif(not HAS_CC, reason="no C compiler")


def per_row(data: np.ndarray) -> bytes:
    """The reference text: Python's '%.17g' of every value, row by row."""
    return "".join(format_row(r) + "\n" for r in data).encode()


def from_bits(bits: int) -> float:
    return struct.unpack("<d", struct.pack("<Q", bits))[0]


def steps_from(x: float, steps: int) -> float:
    """The double `steps` doubles above (below, if negative) x."""
    for _ in range(abs(steps)):
        x = float(np.nextafter(x, np.inf if steps > 0 else -np.inf))
    return x


def tie(k: int, m: int) -> float:
    """An odd multiple of 2^-(17-k) in [10^k, 10^(k+1)) (the m-th, wrapping round):
    18 significant digits, the last a 5, so '%.17g' must round half to even."""
    e = 17 - k
    scale = Fraction(10) ** k * 2**e
    low, high = math.ceil(scale), min(math.ceil(10 * scale), 2**53)
    odd = (low + m % (high - low)) | 1
    return (odd if odd < high else odd - 2) / 2**e


FINITE = st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=True, width=64)
SUBNORMAL = st.integers(1, 2**52 - 1).map(from_bits)
HUGE_TINY = st.one_of(st.floats(1e250, 1.7976931348623157e308), st.floats(5e-324, 1e-250))
INTEGERS = st.one_of(st.integers(-2**64, 2**64).map(float), st.integers(-10**17, 10**17).map(float))
NEAR_POWERS = st.builds(lambda k, s: steps_from(float(f"1e{k}"), s), st.integers(-323, 308), st.integers(-3, 3))
STYLE_SWITCH = st.builds(steps_from, st.sampled_from([1e-5, 1e-4, 1e16, 1e17, 9.9999999999999995e-5,
                                                      99999999999999999.0]), st.integers(-40, 40))
TIES = st.builds(tie, st.integers(-5, 12), st.integers(0, 2**60))
ANY = st.one_of(FINITE, SUBNORMAL, HUGE_TINY, INTEGERS, NEAR_POWERS, STYLE_SWITCH, TIES, st.sampled_from([0.0, -0.0]))
SIGNED = st.builds(lambda x, minus: -x if minus else x, ANY, st.booleans())


@pytest.fixture(scope="module")
def compiled() -> object:
    fn = formatter(BUILD_AT)
    if fn is None:
        pytest.skip("no C compiler")
    return fn


@pytest.fixture
def fresh_library():
    """The formatter built or loaded anew (a test changes the compiler or cache), and after."""
    library.cache_clear()
    yield
    library.cache_clear()


def test_tie_values_have_18_digits_ending_in_5() -> None:
    for k in range(-5, 13):
        for m in (0, 7, 2**40 + 3):
            digits = Decimal(tie(k, m)).normalize().as_tuple().digits
            assert len(digits) == 18 and digits[-1] == 5, (k, m, Decimal(tie(k, m)))


@needs_cc
@settings(max_examples=250, deadline=None)
@given(st.lists(SIGNED, min_size=1, max_size=30))
def test_compiled_text_is_python_percent_17g_byte_for_byte(compiled, values: list[float]) -> None:
    block = np.array(values).reshape(-1, 1)
    assert csv_block(block, compiled) == per_row(block)


@needs_cc
@settings(max_examples=300, deadline=None)
@given(st.integers(-5, 12), st.integers(0, 2**60), st.booleans())
def test_ties_round_half_to_even_as_python(compiled, k: int, m: int, minus: bool) -> None:
    x = -tie(k, m) if minus else tie(k, m)
    assert csv_block(np.array([[x, 1.0]]), compiled) == f"{x:.17g},1\n".encode()


@needs_cc
@pytest.mark.parametrize("name", ["normal", "wide exponents", "integers below 2^64", "uniform bits", "ties",
                                  "1e15 and up"])
def test_compiled_formatter_writes_ordinary_values_itself(compiled, name: str) -> None:
    """Python's '%' is for the rare value only: a block of these (ties included) never
    stops the C call, and its text is Python's."""
    rng = np.random.default_rng(11)
    n = 50_000
    values = {"normal": lambda: rng.standard_normal(n),
              "wide exponents": lambda: rng.standard_normal(n) * 10.0 ** rng.integers(-240, 240, n),
              "integers below 2^64": lambda: rng.integers(0, 2**64, n, dtype=np.uint64).astype(float),
              "uniform bits": lambda: rng.integers(0, 2**64, n, dtype=np.uint64).view(float),
              "ties": lambda: np.array([tie(k, m) for k, m in zip(rng.integers(-5, 13, n), rng.integers(0, 2**60, n))]),
              "1e15 and up": lambda: rng.uniform(1e15, 1e17, n)}[name]()  # half of [2^49, 2^50) are ties
    if name == "uniform bits":  # whatever is left to Python is the rare kinds only
        values = values[np.isfinite(values) & (np.abs(values) >= 1e-13) & (np.abs(values) <= 1e250)]
    values = np.ascontiguousarray(values[:values.size // 5 * 5])
    stop = ctypes.c_long(-1)
    out = np.empty(values.size * compiled_csv.WIDEST + compiled_csv.ROOM, np.uint8)
    written = compiled(values.ctypes.data, 0, values.size, 5, out.ctypes.data, ctypes.byref(stop))
    assert stop.value == values.size
    assert out[:written].tobytes() == per_row(values.reshape(-1, 5))


@needs_cc
def test_nan_and_inf_are_written_as_python_writes_them(compiled) -> None:
    negative_nan = -np.array([np.nan])[0]
    block = np.array([[np.nan, negative_nan, np.inf, -np.inf, -0.0, 0.0]])
    assert np.signbit(block[0, 1])
    assert csv_block(block, compiled) == b"nan,nan,inf,-inf,-0,0\n" == per_row(block)


@needs_cc
@pytest.mark.parametrize("column", [0, 3, 6])
def test_rows_keep_their_order_width_and_separators_around_a_value_left_to_python(compiled, column: int) -> None:
    rng = np.random.default_rng(column)
    block = rng.standard_normal((50, 7)) * 10.0 ** rng.integers(-8, 20, (50, 7))
    block[::7, column] = tie(3, 12345)  # stops the C call: Python writes it and the separator
    block[1::9, column] = 1e300 / 3  # outside [1e-250, 1e250]: Python too
    lines = csv_block(block, compiled).split(b"\n")
    assert lines[-1] == b"" and len(lines) == 51
    back = np.array([[float(v) for v in line.split(b",")] for line in lines[:-1]])
    assert back.shape == (50, 7) and back.tobytes() == block.tobytes()
    assert b"\n".join(lines) == per_row(block)


@needs_cc
def test_csv_file_from_many_blocks_on_all_cores_is_in_order(compiled, tmp_path: Path) -> None:
    assert formatter(1) is not None  # built: the writer uses it for every block
    rng = np.random.default_rng(4)
    data = rng.standard_normal((9000, 9)) * 10.0 ** rng.integers(-6, 18, (9000, 9))
    data[::101, 2] = np.nan
    assert write_csv(tmp_path / "t.csv", [f"c{k}" for k in range(9)], (data[k:k + 1500] for k in range(0, 9000, 1500))) \
        == 9000
    assert (tmp_path / "t.csv").read_bytes() == b"c0,c1,c2,c3,c4,c5,c6,c7,c8\n" + per_row(data)


@needs_cc
def test_csv_writer_holds_a_few_blocks_not_the_table(compiled, tmp_path: Path) -> None:
    """100 blocks of 1024 x 20 values are 16 MB of doubles and ~40 MB of text; the
    writer's own allocations stay under 20 MB (at most AHEAD blocks per core wait:
    ~3 MB on 2 cores)."""
    block = np.random.default_rng(2).standard_normal((1024, 20))
    tracemalloc.start()
    try:
        write_csv(tmp_path / "big.csv", [f"c{k}" for k in range(20)], (block + k for k in range(100)))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20, f"peak {peak / 2**20:.1f} MB"
    assert (tmp_path / "big.csv").stat().st_size > 30e6


@needs_cc
def test_formatter_source_compiles_with_every_warning_as_an_error(tmp_path: Path) -> None:
    (tmp_path / "f.c").write_text(compiled_csv.render())
    cc = next(c for c in ("cc", "gcc", "clang") if shutil.which(c))
    result = subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-c",
                             str(tmp_path / "f.c"), "-o", str(tmp_path / "f.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


@needs_cc
def test_formatter_is_loaded_from_a_checked_cache_entry_and_a_damaged_one_is_rebuilt(fresh_library, monkeypatch,
                                                                                     tmp_path: Path, capsys) -> None:
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    folder = cache.cached_entry(compiled_csv.entry(), compiled_csv._make, (compiled_csv.LIBRARY,))
    assert folder.parent == tmp_path / "cache" and cache.verify(folder) is None
    so = folder / compiled_csv.LIBRARY
    built = bytearray(so.read_bytes())
    built[len(built) // 2] ^= 0xFF  # one byte changed: not what was built
    damaged = bytes(built)
    so.unlink()  # a new file, not the one a loaded library maps
    so.write_bytes(damaged)
    fn = library()
    assert "does not match its recorded sha256" in capsys.readouterr().err
    assert cache.verify(folder) is None and so.read_bytes() != damaged
    assert csv_block(np.array([[0.1, 2.0]] * 5000), fn) == b"0.10000000000000001,2\n" * 5000


def test_without_a_compiler_the_numpy_formatter_writes_the_same_file(fresh_library, monkeypatch, tmp_path: Path,
                                                                     capsys) -> None:
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert formatter(10**6) is None
    rng = np.random.default_rng(8)
    data = rng.standard_normal((3000, 12)) * 10.0 ** rng.integers(-30, 30, (3000, 12))
    data[5] = [np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324, 1e16, 1e17, 1e-5, tie(2, 9), 2.0**64, 1e23]
    assert write_csv(tmp_path / "t.csv", ["c"] * 12, [data]) == 3000
    assert (tmp_path / "t.csv").read_bytes() == (",".join(["c"] * 12) + "\n").encode() + per_row(data)
    assert capsys.readouterr().err == ""  # the fallback is silent: same bytes, only slower


def test_a_failing_compiler_falls_back_to_numpy_silently(fresh_library, monkeypatch, tmp_path: Path, capsys) -> None:
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", "false")  # found, and fails on everything
    assert formatter(10**6) is None
    assert csv_block(np.array([[0.1, -2.5e-7]]), None) == b"0.10000000000000001,-2.4999999999999999e-07\n"
    assert capsys.readouterr().err == ""
    assert [p.name for p in (tmp_path / "cache").iterdir()] == []  # no half-built entry left


def test_a_small_table_uses_the_formatter_only_once_it_is_in_the_cache(fresh_library, monkeypatch,
                                                                       tmp_path: Path) -> None:
    """A short run never waits for gcc; once a large table built the formatter, every table uses it."""
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    built: list[Path] = []
    make = compiled_csv._make
    monkeypatch.setattr(compiled_csv, "_make", lambda folder: (built.append(folder), make(folder)))
    assert formatter(BUILD_AT - 1) is None and built == []
    if not HAS_CC:
        return
    assert formatter(BUILD_AT) is not None and len(built) == 1
    library.cache_clear()  # a later process: the cache holds it
    assert formatter(10) is not None and len(built) == 1


@pytest.mark.parametrize("way", ["numpy", "compiled"])
@pytest.mark.parametrize("variants", [6, 3000])
def test_sweep_csv_is_the_row_by_row_text(tmp_path: Path, monkeypatch, variants: int, way: str) -> None:
    """The sweep table, formatted by either formatter, in the text it had when written row by row."""
    if way == "numpy":
        monkeypatch.setattr("symid.study.table.formatter", lambda values: None)
    elif formatter(BUILD_AT) is None:
        pytest.skip("no C compiler")
    rng = np.random.default_rng(variants)
    values = rng.uniform(0.1, 0.5, (variants, 2))
    figures = rng.standard_normal((variants, 3)) * 10.0 ** rng.integers(-9, 9, (variants, 3))
    figures[1] = [np.nan, -0.0, np.inf]
    status = (np.arange(variants) % 5).astype(np.int8)
    t_end = np.where(status == 0, 1.0, rng.uniform(0, 1, variants))
    table = SweepTable("grid", ("L_rod", "n"), values, Figures(("a.x", "b.y", "m.T"), figures, status, t_end),
                       np.arange(variants))
    table.write(tmp_path / "s.csv")
    from symid.study.figures import STATUS

    expected = "variant,L_rod,n,status,t_end,a.x,b.y,m.T,cond_worst\n" + "".join(
        f"{k},{format_row(values[k])},{STATUS[status[k]]},{format_row([t_end[k], *figures[k], 0.0])}\n"
        for k in range(variants))
    assert (tmp_path / "s.csv").read_text() == expected
