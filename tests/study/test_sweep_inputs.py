"""Every bad input of `symid sweep` is one line on stderr and exit 2, before any solving."""

from __future__ import annotations

from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.study import design as vary

CRANK = str(api.example("slider_crank"))


def run(tmp_path: Path, capsys, *args: str) -> tuple[int, str]:
    status = main(["sweep", CRANK, "--steps", "3", "-o", str(tmp_path / "out.csv"), *args])
    err = capsys.readouterr().err
    return status, err


BAD = {
    "grid_two_parts": (["--grid", "L_rod=0.2:0.3"], "--grid L_rod=0.2:0.3: expected NAME=LO:HI:N"),
    "grid_no_equals": (["--grid", "L_rod"], "expected NAME=LO:HI:N"),
    "grid_n_zero": (["--grid", "L_rod=0.2:0.3:0"], "N must be a whole number >= 1"),
    "grid_n_not_whole": (["--grid", "L_rod=0.2:0.3:2.5"], "N must be a whole number >= 1, not '2.5'"),
    "grid_lo_above_hi": (["--grid", "L_rod=0.3:0.2:3"], "LO 0.3 is greater than HI 0.2"),
    "grid_not_a_number": (["--grid", "L_rod=a:0.3:3"], "LO: 'a' is not a finite number"),
    "grid_infinite": (["--grid", "L_rod=0:inf:3"], "HI: 'inf' is not a finite number"),
    "unknown_parameter": (["--grid", "L_bar=0.2:0.3:2"], "--grid: no parameter 'L_bar' (base parameters: L_crank"),
    "derived_parameter": (["--grid", "omega=10:20:2"],
                          "'omega' is a derived parameter (omega = 2*pi*n): vary the base parameters"),
    "derived_in_sample": (["--sample", "3", "--normal", "omega=10,1"], "'omega' is a derived parameter"),
    "varied_twice": (["--grid", "n=1:2:2", "--grid", "n=3:4:2"], "parameter 'n' is varied twice"),
    "normal_sd_zero": (["--sample", "3", "--normal", "n=5,0"], "--normal n=5,0: SD must be > 0, not 0"),
    "normal_sd_negative": (["--sample", "3", "--normal", "n=5,-1"], "SD must be > 0"),
    "normal_one_number": (["--sample", "3", "--normal", "n=5"], "--normal n=5: expected NAME=MEAN,SD"),
    "uniform_hi_below_lo": (["--sample", "3", "--uniform", "n=6,5"], "--uniform n=6,5: HI 5 is less than LO 6"),
    "uniform_span_overflows": (["--sample", "3", "--uniform", "n=-1e308,1e308"],
                               "--uniform n=-1e308,1e308: the span HI - LO is past the largest double"),
    "grid_span_overflows": (["--grid", "n=-1e308:1e308:3"],
                            "--grid n=-1e308:1e308:3: the span HI - LO is past the largest double"),
    "normal_draws_overflow": (["--sample", "50", "--normal", "n=1.7e308,1e307", "--seed", "1"],
                              "--normal n=1.7e308,1e307: draws past the largest double"),
    "seed_negative": (["--sample", "3", "--uniform", "n=4,6", "--seed", "-1"],
                      "argument --seed: must be a whole number from 0 to"),
    "sample_no_distribution": (["--sample", "3"], "--sample: name the parameters to draw"),
    "sample_zero": (["--sample", "0", "--normal", "n=5,1"], "argument --sample: must be a whole number from 1 to"),
    "normal_without_sample": (["--normal", "n=5,1"], "--normal needs --sample N"),
    "grid_and_sample": (["--grid", "n=1:2:2", "--sample", "3", "--normal", "m_rod=1,0.1"],
                        "not --grid and --sample together"),
    "no_variants": ([], "give the variants as one of --grid"),
    "too_many": (["--grid", "n=1:2:1001", "--grid", "m_rod=1:2:1000"],
                 f"1001000 variants, more than the {vary.MAX_VARIANTS} a sweep allows"),
    "one_grid_too_many": (["--grid", "n=1:2:99999999999999999999"],
                          f"--grid: 99999999999999999999 variants, more than the {vary.MAX_VARIANTS} a sweep"),
    "set_and_varied": (["--grid", "n=1:2:2", "--set", "n=3"], "parameter 'n' is both fixed by --set and varied"),
    "workers_zero": (["--grid", "n=1:2:2", "--workers", "0"], "argument --workers: must be a whole number from 1 to"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_option_is_one_line_exit_2(tmp_path, capsys, case):
    args, message = BAD[case]
    status, err = run(tmp_path, capsys, *args)
    assert status == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
    assert not (tmp_path / "out.csv").exists()


TABLES = {
    "unknown_column": ("L_rod,colour\n0.3,1\n", "--table {path}: no parameter 'colour'"),
    "derived_column": ("omega\n10\n", "'omega' is a derived parameter (omega = 2*pi*n)"),
    "missing_cell": ("L_rod,n\n0.3,5\n0.3,\n", "{path}: line 3, column 'n': missing value"),
    "short_row": ("L_rod,n\n0.3\n", "{path}: line 2: 1 cells, the header has 2"),
    "not_a_number": ("L_rod,n\n0.3,five\n", "{path}: line 2, column 'n': 'five' is not a finite number"),
    "nan_cell": ("L_rod,n\n0.3,nan\n", "'nan' is not a finite number"),
    "header_only": ("L_rod,n\n", "--table {path}: no variants"),
    "empty": ("", "--table {path}: no header row"),
    "duplicate_header": ("n,n\n1,2\n", "{path}: line 1: header names must be distinct"),
}


@pytest.mark.parametrize("case", sorted(TABLES))
def test_bad_table_is_one_line_exit_2_naming_file_and_line(tmp_path, capsys, case):
    text, message = TABLES[case]
    path = tmp_path / "v.csv"
    path.write_text(text, encoding="utf-8")
    status, err = run(tmp_path, capsys, "--table", str(path))
    assert status == 2, err
    assert err.count("\n") == 1 and message.format(path=path) in err, err


def test_missing_table_file_is_one_line_exit_2(tmp_path, capsys):
    status, err = run(tmp_path, capsys, "--table", str(tmp_path / "none.csv"))
    assert status == 2 and err.count("\n") == 1 and "none.csv" in err and "cannot read" in err


def test_output_in_no_folder_is_exit_2_before_solving(tmp_path, capsys):
    status = main(["sweep", CRANK, "--grid", "n=1:2:2", "-o", str(tmp_path / "no" / "out.csv")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "no folder" in err


def test_unreachable_scheduler_is_exit_2_after_a_bounded_wait(tmp_path, capsys, monkeypatch):
    import socket

    from symid.study import cluster

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 1.0)
    # the wait's bound is CONNECT_TIMEOUT, named in the message (no wall-clock assertion)
    status, err = run(tmp_path, capsys, "--grid", "n=1:2:2", "--scheduler", f"tcp://127.0.0.1:{port}")
    assert status == 2 and err.count("\n") == 1, err
    assert f"--scheduler tcp://127.0.0.1:{port}: no scheduler reached" in err  # refused: said at once
