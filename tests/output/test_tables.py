"""The table writers: CSV text identical to Python's '%.17g' row by row, .npz
in bounded memory, Parquet; exact round trips; partial runs kept."""

from __future__ import annotations

import struct
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from symid import api
from symid.cli import main
from symid.errors import AnalysisError
from symid.output.digits import csv_block
from symid.output.npz import read_npz, write_npz
from symid.output.results import format_row
from symid.output.tables import blocks, read_parquet, write_csv, write_parquet, write_table

SPECIAL = [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
           1e16, 1e17, 1e22, 1e23, 0.1, 1e-4, 9.9999999999999995e-5, 1e-5, 2.0**-25, 99999999999999999.0,
           9999999999999998.0, 123456789012345678.0, 1e-250, 1e250, 0.5, -1.5, 3.0, 1e15 + 0.5]


def per_row(data: np.ndarray) -> bytes:
    """The text of the row-by-row writer these blocks replace: `format_row` per row."""
    return "".join(format_row(r) + "\n" for r in data).encode()


def same_doubles(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal bit for bit (so -0.0 differs from 0.0 and nan equals nan)."""
    return a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("name", ["uniform bits", "normal", "wide exponents", "integers", "dyadic", "special"])
def test_block_text_is_python_percent_17g_byte_for_byte(name: str) -> None:
    rng = np.random.default_rng(17)
    n = 60_000
    data = {
        "uniform bits": lambda: rng.integers(0, 2**64, n, dtype=np.uint64).view(float),
        "normal": lambda: rng.standard_normal(n),
        "wide exponents": lambda: rng.standard_normal(n) * 10.0 ** rng.integers(-320, 308, n),
        "integers": lambda: rng.integers(-10**17, 10**17, n).astype(float),
        "dyadic": lambda: rng.integers(-2**53, 2**53, n) * 2.0 ** rng.integers(-80, 20, n),
        "special": lambda: np.array(SPECIAL + [np.nextafter(10.0 ** k, d) for k in range(-30, 30)
                                               for d in (0, np.inf)]),
    }[name]().reshape(-1, 4 if name != "special" else 1)
    assert csv_block(data) == per_row(data)


@settings(max_examples=100, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=12),
                  elements=st.one_of(st.floats(allow_subnormal=True, width=64),
                                     st.integers(-2**60, 2**60).map(float),
                                     st.sampled_from(SPECIAL))))
def test_any_block_formats_as_python_and_reads_back_exactly(data: np.ndarray) -> None:
    text = csv_block(data)
    assert text == per_row(data)
    back = np.array([[float(v) for v in line.split(b",")] for line in text.splitlines()])
    finite = np.isfinite(data)
    assert same_doubles(back[finite], data[finite])  # -0.0 stays -0.0
    assert np.array_equal(np.isnan(back), np.isnan(data))


def test_csv_file_equals_the_row_writer_and_keeps_rows_before_a_failure(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    data = rng.standard_normal((2500, 5)) * 10.0 ** rng.integers(-6, 6, (2500, 5))

    def items():  # rows and blocks mixed, as the compiled loop's fallback instants come
        yield data[0]
        yield data[1:1500]
        yield from data[1500:2000]
        raise AnalysisError("Newton did not converge", 1.0, 2000)

    header = ["t", "a.x", "a.y", "b.x", "b.y"]
    with pytest.raises(AnalysisError):
        write_csv(tmp_path / "r.csv", header, items())
    assert (tmp_path / "r.csv").read_bytes() == ("t,a.x,a.y,b.x,b.y\n").encode() + per_row(data[:2000])


def test_blocks_gathers_rows_and_cuts_blocks_in_order() -> None:
    rows = [np.full(3, k, float) for k in range(9)]
    out = list(blocks([*rows[:2], np.vstack(rows[2:8]), rows[8]], 3, size=4))
    assert [b.shape for b in out] == [(2, 3), (4, 3), (2, 3), (1, 3)]
    assert np.array_equal(np.vstack(out)[:, 0], np.arange(9))


@pytest.mark.parametrize("total", [None, 10, 5000, 100_000])
def test_npz_columns_equal_the_rows_whatever_count_was_announced(tmp_path: Path, total: int | None) -> None:
    """Preallocated for `total` rows; fewer or more (the scratch grows) come out the same."""
    rng = np.random.default_rng(5)
    data = rng.standard_normal((5000, 3))
    assert write_npz(tmp_path / "a.npz", ["t", "a.x", "b.y"], (data[k:k + 700] for k in range(0, 5000, 700)),
                     total) == 5000
    back = read_npz(tmp_path / "a.npz")
    assert back.columns == ["t", "a.x", "b.y"] and same_doubles(back.data, data)


def test_npz_writer_holds_one_block_not_the_table(tmp_path: Path) -> None:
    """200 000 rows x 20 columns are 32 MB; the writer's own allocations stay under 4 MB."""
    block = np.arange(1024 * 20, dtype=float).reshape(1024, 20)
    tracemalloc.start()
    try:
        write_npz(tmp_path / "big.npz", [f"c{k}" for k in range(20)], (block + k for k in range(196)), 196 * 1024)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 * 2**20, f"peak {peak / 2**20:.1f} MB"
    with np.load(tmp_path / "big.npz") as archive:
        assert archive["c3"].shape == (196 * 1024,) and archive["c3"][-1] == block[-1, 3] + 195


def test_parquet_round_trips_names_order_and_doubles(tmp_path: Path) -> None:
    data = np.array([[0.0, -0.0, 1e-310], [0.1, np.inf, -1e300], [np.nan, 2.5, 3.0]])
    assert write_table(tmp_path / "a.parquet", ["t", "a.x", "motor.T_j"], data) == 3
    names, back = read_parquet(tmp_path / "a.parquet")
    assert names == ["t", "a.x", "motor.T_j"] and same_doubles(back, data)


def test_parquet_keeps_the_rows_before_a_failure_and_nothing_on_another_error(tmp_path: Path) -> None:
    def rows(fail: BaseException):
        for k in range(7):
            yield np.array([k, 2.0 * k])
        raise fail

    with pytest.raises(AnalysisError):
        write_parquet(tmp_path / "a.parquet", ["t", "x"], rows(AnalysisError("singular", 7.0, 7)))
    names, back = read_parquet(tmp_path / "a.parquet")
    assert np.array_equal(back[:, 1], 2.0 * np.arange(7))
    with pytest.raises(KeyboardInterrupt):
        write_parquet(tmp_path / "b.parquet", ["t", "x"], rows(KeyboardInterrupt()))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.parquet"]


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_solve_writes_the_same_doubles_to_csv_npz_and_parquet(tmp_path: Path, capsys, backend: str) -> None:
    example = str(api.example("slider_crank"))
    for suffix in ("csv", "npz", "parquet"):
        assert main(["solve", example, "--backend", backend, "--steps", "41", "-o", str(tmp_path / f"r.{suffix}")]) == 0
    text = (tmp_path / "r.csv").read_text().splitlines()
    header = text[0].split(",")
    table = np.array([[float(v) for v in line.split(",")] for line in text[1:]])
    names, parquet = read_parquet(tmp_path / "r.parquet")
    npz = read_npz(tmp_path / "r.npz")
    assert names == header == npz.columns
    assert same_doubles(parquet, table) and same_doubles(npz.data, table)


def test_parquet_without_pyarrow_is_one_line_exit_2_before_solving(tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow raises ImportError
    assert main(["solve", str(api.example("four_bar")), "--steps", "5", "-o", str(tmp_path / "r.parquet")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pyarrow" in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_float_bits_helper_sees_negative_zero() -> None:
    assert not same_doubles(np.array([0.0]), np.array([-0.0]))
    assert struct.pack("<d", -0.0) != struct.pack("<d", 0.0)
