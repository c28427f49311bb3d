"""Plots of a sweep: each artist carries the table's data, failed variants are drawn."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.output import sweep_plot
from symid.study import design as vary

PNG = b"\x89PNG\r\n\x1a\n"
CRANK = str(api.example("slider_crank"))
NAMES = ("motor.effort_peak", "motor.effort_rms")


def artists(fig, gid: str) -> list:
    """Every artist of the figure (lines, collections, patches) with this gid."""
    return [a for ax in fig.axes for a in (*ax.lines, *ax.collections, *ax.patches) if a.get_gid() == gid]


def synthetic(values: np.ndarray, failed: list[int]) -> tuple[np.ndarray, list[str]]:
    figures = np.column_stack([values.sum(axis=1), values.prod(axis=1)])
    status = ["ok"] * len(values)
    for k in failed:
        status[k] = "not_converged"
    return figures, status


def test_layout_of_recognizes_grids_and_samples():
    g = vary.grid(["a=0:1:3", "b=0:2:4"])
    assert sweep_plot.layout_of(g.names, g.values) == "grid2"
    assert sweep_plot.layout_of(("a",), vary.grid(["a=0:1:5"]).values) == "grid1"
    assert sweep_plot.layout_of(g.names, g.values[::-1]) == "sample"  # not in product order
    s = vary.sample(20, ["a=0,1"], ["b=0,1"], 0)
    assert sweep_plot.layout_of(s.names, s.values) == "sample"


def test_two_parameter_grid_is_a_filled_contour_per_figure_with_failed_points_crossed():
    g = vary.grid(["a=0:1:3", "b=0:2:4"])
    figures, status = synthetic(g.values, [5])
    fig = sweep_plot.figures_of(g.names, g.values, NAMES, figures, status, "s")["figures"]
    for name in NAMES:
        assert len(artists(fig, f"contour:{name}")) == 1
        (cross,) = artists(fig, f"failed:{name}")
        assert cross.get_xdata().tolist() == [g.values[5, 0]] and cross.get_ydata().tolist() == [g.values[5, 1]]
    ax = artists(fig, f"contour:{NAMES[0]}")[0].axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("a", "b")


def test_one_parameter_is_lines_with_failed_variants_at_their_partial_figures():
    g = vary.grid(["a=1:2:6"])
    figures, status = synthetic(g.values, [2])
    fig = sweep_plot.figures_of(g.names, g.values, NAMES, figures, status, "s")["figures"]
    for k, name in enumerate(NAMES):
        (line,) = artists(fig, f"line:{name}")
        expected = figures[:, k].copy()
        expected[2] = np.nan
        np.testing.assert_array_equal(line.get_xdata(), g.values[:, 0])
        np.testing.assert_array_equal(line.get_ydata(), expected)
        (cross,) = artists(fig, f"failed:{name}")
        assert cross.get_ydata().tolist() == [figures[2, k]]


def test_sample_is_histograms_with_percentiles_and_scatter_against_the_primary_figure():
    s = vary.sample(200, ["a=1,0.1"], ["b=2,3"], 4)
    figures, status = synthetic(s.values, [0, 7])
    ok = np.array([x == "ok" for x in status])
    out = sweep_plot.figures_of(s.names, s.values, NAMES, figures, status, "s", "sample")
    hist, scatter = out["figures"], out["scatter"]
    for k, name in enumerate(NAMES):
        bars = artists(hist, f"hist:{name}")
        assert sum(b.get_height() for b in bars) == 198  # the variants that ran to the end
        for p in (50, 95, 99):
            (line,) = artists(hist, f"P{p}:{name}")
            assert line.get_xdata()[0] == pytest.approx(np.percentile(figures[ok, k], p), rel=1e-15)
        (ticks,) = artists(hist, f"failed:{name}")
        assert sorted(ticks.get_xdata()) == sorted(figures[~ok, k])
    for k, name in enumerate(s.names):
        (points,) = artists(scatter, f"scatter:{name}")
        np.testing.assert_array_equal(points.get_offsets(), np.column_stack([s.values[ok, k], figures[ok, 0]]))
        assert points.axes.get_ylabel() == NAMES[0]
        (cross,) = artists(scatter, f"failed:{name}")
        assert cross.get_xdata().tolist() == s.values[~ok, k].tolist()


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_symid_plot_of_a_sweep_table_writes_its_pngs(tmp_path, capsys, suffix):
    out = tmp_path / f"study{suffix}"
    assert main(["sweep", CRANK, "--steps", "5", "--grid", "L_rod=0.08:0.3:3", "-o", str(out), "--plot"]) == 0
    plotted = capsys.readouterr().out.splitlines()[1:]
    assert plotted == [str(tmp_path / "study_figures.png")]
    first = (tmp_path / "study_figures.png").read_bytes()
    (tmp_path / "study_figures.png").unlink()
    assert main(["plot", str(out), "-o", str(tmp_path / "again")]) == 0
    assert capsys.readouterr().out.splitlines() == [str(tmp_path / "again" / "study_figures.png")]
    again = (tmp_path / "again" / "study_figures.png").read_bytes()
    assert first[:8] == again[:8] == PNG and len(again) > 20_000


def test_symid_plot_refuses_a_mechanism_with_a_sweep_table(tmp_path, capsys):
    out = tmp_path / "study.csv"
    assert main(["sweep", CRANK, "--steps", "3", "--grid", "n=4:5:2", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["plot", str(out), "--mechanism", CRANK]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a sweep table is plotted alone" in err
