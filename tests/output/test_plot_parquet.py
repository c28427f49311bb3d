"""Found trying symid as a new user: `symid plot RESULTS.parquet` (a solve's
Parquet table, as docs/plots.md lists) is plotted as a results table, not
refused as a sweep table; a sweep's Parquet table is still a sweep."""

from __future__ import annotations

from pathlib import Path

import pytest

from symid import api
from symid import cli

pytest.importorskip("pyarrow")
SLIDER_CRANK = api.example("slider_crank")


def test_a_solve_parquet_table_plots_with_its_mechanism(tmp_path, capsys):
    table = tmp_path / "sc.parquet"
    assert cli.main(["solve", str(SLIDER_CRANK), "--steps", "11", "--backend", "numpy", "-o", str(table)]) == 0
    capsys.readouterr()
    status = cli.main(["plot", str(table), "--mechanism", str(SLIDER_CRANK), "-o", str(tmp_path)])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert (tmp_path / "sc_efforts.png").stat().st_size > 0
    assert (tmp_path / "sc_mechanism.png").stat().st_size > 0


def test_a_sweep_parquet_table_still_plots_as_a_sweep(tmp_path, capsys):
    table = tmp_path / "study.parquet"
    assert cli.main(["sweep", str(SLIDER_CRANK), "--grid", "n=5:6:2", "--steps", "11", "--backend", "numpy",
                     "--workers", "1", "-o", str(table)]) == 0
    capsys.readouterr()
    assert cli.main(["plot", str(table), "-o", str(tmp_path)]) == 0
    assert (tmp_path / "study_figures.png").stat().st_size > 0
