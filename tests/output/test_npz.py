"""The .npz results: arrays named as the CSV columns, atomic, partial runs kept."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.errors import AnalysisError
from symid.output import npz
from symid.output.npz import read_npz, write_npz

HEADER = ["t", "crank.x", "motor.T_j"]


def rows(n: int, fail_after: int | None = None, error: Exception | None = None):
    for k in range(n):
        if fail_after is not None and k == fail_after:
            raise error or AnalysisError("Phi_q is singular", float(k), k)
        yield np.array([k, 2.0 * k, -1.0 / (k + 1)])


def test_solve_to_npz_has_the_csv_columns_with_the_same_values(tmp_path, capsys):
    example = str(api.example("four_bar"))
    assert main(["solve", example, "-o", str(tmp_path / "r.csv"), "--steps", "11"]) == 0
    assert main(["solve", example, "-o", str(tmp_path / "r.npz"), "--steps", "11"]) == 0
    assert f"{tmp_path / 'r.npz'}: 11 instants" in capsys.readouterr().out
    header = (tmp_path / "r.csv").read_text().splitlines()[0].split(",")
    table = np.loadtxt(tmp_path / "r.csv", delimiter=",", skiprows=1)
    with np.load(tmp_path / "r.npz") as archive:
        assert archive.files == header
        for k, name in enumerate(header):
            assert archive[name].shape == (11,)
            np.testing.assert_array_equal(archive[name], table[:, k])  # 17 digits round-trip exactly


def test_write_then_read_round_trips_names_order_and_values(tmp_path):
    assert write_npz(tmp_path / "a.npz", HEADER, rows(4)) == 4
    back = read_npz(tmp_path / "a.npz")
    assert back.columns == HEADER
    np.testing.assert_array_equal(back.data, np.array(list(rows(4))))


def test_a_failed_analysis_keeps_the_solved_rows_and_re_raises(tmp_path):
    with pytest.raises(AnalysisError):
        write_npz(tmp_path / "a.npz", HEADER, rows(10, fail_after=3))
    back = read_npz(tmp_path / "a.npz")
    np.testing.assert_array_equal(back["t"], [0.0, 1.0, 2.0])
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]


def test_a_failure_at_the_first_instant_still_writes_empty_columns(tmp_path):
    with pytest.raises(AnalysisError):
        write_npz(tmp_path / "a.npz", HEADER, rows(10, fail_after=0))
    with np.load(tmp_path / "a.npz") as archive:
        assert archive.files == HEADER and archive["t"].shape == (0,)


def test_any_other_error_leaves_no_file_and_no_temporary(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        write_npz(tmp_path / "a.npz", HEADER, rows(10, fail_after=5, error=KeyboardInterrupt()))
    assert list(tmp_path.iterdir()) == []


def test_an_existing_archive_is_replaced_whole(tmp_path):
    write_npz(tmp_path / "a.npz", HEADER, rows(8))
    write_npz(tmp_path / "a.npz", HEADER, rows(2))
    assert len(read_npz(tmp_path / "a.npz").t) == 2
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]


def test_reading_something_else_is_an_input_error(tmp_path):
    from symid.errors import InputError

    bad = tmp_path / "bad.npz"
    bad.write_text("not a zip")
    with pytest.raises(InputError, match="bad.npz"):
        read_npz(bad)


def test_a_write_that_fails_midway_leaves_the_old_archive_whole(tmp_path, monkeypatch):
    """The archive is written to a temporary name and renamed: a disk that
    fills while numpy writes it leaves the previous archive as it was."""
    target = tmp_path / "a.npz"
    write_npz(target, HEADER, rows(8))
    before = target.read_bytes()
    copy = npz._Columns.copy_column

    def full_disk(self, k, out):
        copy(self, k, out)  # some bytes reach the file
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(npz._Columns, "copy_column", full_disk)
    with pytest.raises(Exception, match="No space left on device"):
        write_npz(target, HEADER, rows(3))
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]
