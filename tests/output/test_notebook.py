"""Notebook display and export: short reprs, HTML, a DataFrame, CSV of what is held, a plot."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.output.results import Results
from symid.tools.verify import bundled, verify


@pytest.fixture(scope="module")
def solved() -> tuple[api.Study, Results]:
    study = api.prepare(api.example("slider_crank"), "reference", steps=21)
    return study, study.solve()


def test_results_repr_is_short_and_says_what_was_solved(solved) -> None:
    _, results = solved
    text = repr(results)
    assert len(text) < 400 and "\n" not in text
    assert "slider_crank: 21 instants, t = 0 .. 0.2, 67 columns" in text
    peak = np.max(np.abs(results["motor.T_j"]))
    assert f"peak torque {peak:.4g}" in text


def test_results_html_lists_peaks_and_warnings() -> None:
    results = Results(["t", "a.x"], np.zeros((2, 2)), warnings=["Phi_q is ill-conditioned <here>"])
    html = results._repr_html_()
    assert "2 instants" in html and "ill-conditioned &lt;here&gt;" in html and len(html) < 400


def test_study_repr_gives_sizes_and_state(solved) -> None:
    study, _ = solved
    text = repr(study)
    assert "slider_crank on reference: 3 bodies, 5 constraints, 1 force; ng = 9, nc = 9" in text
    assert "solved: slider_crank: 21 instants" in text
    assert "<li>" in study._repr_html_()
    fresh = api.prepare(api.example("slider_crank"), "reference", steps=3)
    assert "not solved yet" in repr(fresh)


def test_report_repr_is_its_verdict() -> None:
    report = verify(bundled()[0])
    assert repr(report).endswith(f"{len(report.outcomes)} entries, all hold)")
    assert report._repr_html_().startswith("<pre>")


def test_study_write_csv_writes_the_results_it_has_without_solving_again(solved, tmp_path: Path,
                                                                          monkeypatch) -> None:
    study, results = solved

    def no_solving() -> None:
        raise AssertionError("solved again")

    monkeypatch.setattr(study, "rows", no_solving)
    assert study.write_csv(tmp_path / "out.csv") == 21
    data = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    assert np.array_equal(data, results.data)
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]  # atomic: no temporary left


def test_results_write_csv_round_trips_exactly(solved, tmp_path: Path) -> None:
    _, results = solved
    assert results.write_csv(tmp_path / "r.csv") == len(results.data)
    header = (tmp_path / "r.csv").read_text().splitlines()[0].split(",")
    assert header == results.columns
    assert np.array_equal(np.loadtxt(tmp_path / "r.csv", delimiter=",", skiprows=1), results.data)


def test_to_pandas_without_pandas_says_how_to_get_it(solved, monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas then raises ImportError
    with pytest.raises(ImportError, match=r"needs pandas \(python3 -m pip install pandas\)"):
        solved[1].to_pandas()


def test_to_pandas_gives_one_column_per_csv_column(solved, monkeypatch) -> None:
    made = {}
    fake = types.ModuleType("pandas")
    fake.DataFrame = lambda data, columns: made.update(data=data, columns=columns) or "frame"  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "pandas", fake)
    assert solved[1].to_pandas() == "frame"
    assert made["columns"] == solved[1].columns and made["data"] is solved[1].data


def test_results_plot_draws_the_efforts_or_named_columns(solved) -> None:
    import matplotlib.pyplot as plt

    _, results = solved
    fig = results.plot()
    assert fig.axes and fig.axes[0].lines
    fig2 = results.plot("motor.T_j", "crank.phi")
    assert len(fig2.axes[0].lines) == 2
    assert np.array_equal(fig2.axes[0].lines[0].get_ydata(), results["motor.T_j"])
    plt.close("all")
