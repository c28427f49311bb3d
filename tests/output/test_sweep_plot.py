"""Plots of a sweep: each artist carries the table's data, failed variants are drawn."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.output import sweep_plot
from symid.study import design as vary
from tiers import first_quick

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


@pytest.mark.slow  # a sweep and its figures twice; the sweep plots' other tests stay in the quick tier
@pytest.mark.parametrize("suffix", first_quick([".parquet", ".csv"]))
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


# a driven pendulum whose mass moves in its 16th digit over a two-parameter
# grid: every figure is constant but for its last digit or two, and the angle
# driver's force_peak is 0 by construction (its reaction is a pure couple)
FLAT = """[mechanism]
name = "flat"
gravity = [0.0, -9.81]

[parameters]
a = 0.3
b = 0.7

[analysis]
t1 = 1.0
steps = 11

[[body]]
name = "bar"
mass = "1.5 + 1e-15*a*b"
inertia = 0.02
q0 = [0.5, 0.0, 0.0]

[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "bar"
si = [0.0, 0.0]
sj = [-0.5, 0.0]

[[constraint]]
name = "drive"
type = "relative_angle_driver"
i = "ground"
j = "bar"
f = "sin(t)"
"""
SHOWN = ("drive.effort_peak", "drive.effort_t_peak", "drive.effort_rms", "drive.power_peak", "pin.force_peak")


@pytest.mark.slow  # 26 s under load
def test_sweep_and_plot_of_a_grid_whose_figures_are_constant_but_for_the_last_digit(tmp_path):
    """As a user runs them: `symid sweep --plot` and `symid plot` exit 0, no
    traceback, the PNG written, a note per flat figure and for the left-out
    force_peak of the angle driver."""
    import subprocess
    import sys

    from symid.study.table import read

    (tmp_path / "flat.toml").write_text(FLAT)
    out = tmp_path / "flat.csv"
    swept = subprocess.run([sys.executable, "-m", "symid", "sweep", "flat.toml", "--grid", "a=0.1:1.3:4", "--grid",
                            "b=0.2:1.1:3", "-o", "flat.csv", "--plot"], cwd=tmp_path, capture_output=True, text=True)
    table = read(out)
    effort = table.figures.values[:, table.figures.names.index("drive.effort_peak")]
    assert 0 < np.ptp(effort) <= 8 * np.spacing(effort.max())  # the case: a few ulps apart, not equal
    (tmp_path / "again").mkdir()
    plotted = subprocess.run([sys.executable, "-m", "symid", "plot", "flat.csv", "-o", "again"], cwd=tmp_path,
                             capture_output=True, text=True)
    for run, tool, folder in ((swept, "sweep: plot", tmp_path), (plotted, "plot", tmp_path / "again")):
        assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
        assert (folder / "flat_figures.png").read_bytes()[:8] == PNG
        notes = run.stderr.splitlines()
        assert f"symid {tool}: drive.force_peak is 0 at every variant" in "\n".join(notes)
        for name in SHOWN:
            assert any(n.startswith(f"symid {tool}: {name} is constant over the variants") for n in notes), name


def test_flat_figure_is_one_level_and_a_zero_force_peak_is_left_out():
    """On the drawing's data: one band holding every value, no colorbar;
    the zero force_peak has no panel; a sample's flat figure is one bar."""
    g = vary.grid(["a=0:1:3", "b=0:2:4"])
    base = np.nextafter(7.3575, 8.0)
    flat = np.where(np.arange(len(g.values)) % 2, base, np.nextafter(base, 8.0))
    figures = np.column_stack([g.values.sum(axis=1), flat, np.zeros(len(flat))])
    names = ("motor.effort_peak", "motor.effort_rms", "mesh.force_peak")
    notes: list[str] = []
    fig = sweep_plot.figures_of(g.names, g.values, names, figures, ["ok"] * len(flat), "s", notes=notes)["figures"]
    (band,) = artists(fig, "contour:motor.effort_rms")
    assert len(band.levels) == 2 and band.levels[0] < flat.min() and flat.max() < band.levels[1]
    assert len(artists(fig, "contour:motor.effort_peak")[0].levels) == 12
    assert not artists(fig, "contour:mesh.force_peak")
    assert [ax.get_title() for ax in fig.axes if ax.get_visible() and ax.get_label() != "<colorbar>"] == list(
        names[:2])
    assert len(notes) == 2 and notes[0].startswith("mesh.force_peak is 0 at every variant")
    assert notes[1].startswith("motor.effort_rms is constant over the variants")
    s = vary.sample(50, ["a=1,0.1"], [], 4)
    hist = sweep_plot.figures_of(s.names, s.values, names, np.column_stack([s.values[:, 0], flat[:1].repeat(50),
                                 np.zeros(50)]), ["ok"] * 50, "s", "sample")["figures"]
    bars = artists(hist, "hist:motor.effort_rms")
    assert len(bars) == 1 and bars[0].get_height() == 50
