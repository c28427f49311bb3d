"""Every plot of every bundled example renders, and each figure's data is the results'."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from PIL import Image

from symid import api

from symid.output import plot

from symid.output import summary
from symid.output.scene import scene
from symid.cli import main
from symid.io.reader import load, loads
from runshare import key_of, shared_value
from truth import Truth

EXAMPLES = api.examples()
STEPS = 41
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module", params=EXAMPLES)
def solved(request, tmp_path_factory):
    """The example's mechanism and its run, the run solved once per run of the
    tests (any worker: this module's tests of one example may run on both)."""
    mech = load(api.example(request.param), analysis={"steps": STEPS})

    def solve():
        results = api.solve(mech)
        assert results.error is None, results.error
        return results

    return mech, shared_value(tmp_path_factory, key_of("plot-run", api.example(request.param).read_text(), STEPS),
                              solve)


def lines(fig, prefix: str) -> dict[str, object]:
    """gid -> line, for every line of the figure whose gid starts with prefix."""
    return {ln.get_gid(): ln for ax in fig.axes for ln in ax.lines if (ln.get_gid() or "").startswith(prefix)}


def test_every_plot_of_every_example_is_a_png_of_plausible_size(solved, tmp_path):
    mech, results = solved
    written = plot.write_all(results, mech, tmp_path, mech.name)
    assert written.skipped == []
    kinds = ("efforts", "reactions", "mechanism") + (("friction",) if any(c.friction for c in mech.constraints) else ())
    kinds += ("sizing",) if mech.sizing else ()  # drives or bearings (slider_crank_sized)
    assert [p.name for p in written.paths] == [f"{mech.name}_{w}.png" for w in kinds]
    for path in written.paths:
        assert path.read_bytes()[:8] == PNG
        assert 15_000 < path.stat().st_size < 1_500_000, path
        with Image.open(path) as image:
            width, height = image.size
        assert 600 <= width <= 1600 and 300 <= height <= 1600, (path, image.size)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in written.paths)


def test_effort_lines_are_the_driver_efforts_with_labelled_axes(solved):
    mech, results = solved
    fig = plot.efforts_figure(results, mech)
    drawn = lines(fig, "effort:")
    for e in summary.efforts(mech, results):
        line = drawn.pop(f"effort:{e.name}")
        np.testing.assert_array_equal(line.get_xdata(), results.t)
        np.testing.assert_array_equal(line.get_ydata(), e.value)
        assert line.axes.get_ylabel() == f"{e.quantity} [{e.unit}]"
        if e.type == "relative_angle_driver":
            np.testing.assert_array_equal(line.get_ydata(), results[f"{e.name}.T_j"])
    assert drawn == {}
    assert fig.axes[-1].get_xlabel() == "time t [s]"


def test_reaction_lines_are_the_force_magnitudes_of_every_joint(solved):
    mech, results = solved
    fig = plot.reactions_figure(results, mech)
    drawn = lines(fig, "force:")
    for c in mech.constraints:
        role = "i" if c.type == "coordinate_driver" else "j"
        magnitude = np.hypot(results[f"{c.name}.Fx_{role}"], results[f"{c.name}.Fy_{role}"])
        line = drawn.pop(f"force:{c.name}", None)
        if line is None:  # left out only when the force is zero throughout
            # a force left out of the plot is zero to rounding of the run's values
            assert np.max(magnitude) <= 1e-9 * max(np.max(np.abs(results.data[:, 1:])), 1.0), c.name
        else:
            np.testing.assert_array_equal(line.get_ydata(), magnitude)
            assert line.axes.get_ylabel() == "|F| force [N]"
    assert drawn == {}


def test_pins_are_drawn_at_the_joint_points_of_each_instant(solved):
    mech, results = solved
    truth = Truth(mech, results)
    fig = plot.mechanism_figure(results, mech)
    panels = [ax for ax in fig.axes if (ax.get_gid() or "").startswith("instant:")]
    assert 1 < len(panels) <= plot.PANELS
    for ax in panels:
        k = int(ax.get_gid().split(":")[1])
        assert ax.get_xlabel() in ("", "x [m]") and ax.get_aspect() == 1.0
        for c in mech.constraints:
            if c.type in ("revolute", "pin_in_slot"):
                (pin,) = [ln for ln in ax.lines if ln.get_gid() == f"pin:{c.name}"]
                p, _ = truth.point(c.bodies["j"], c.values["sj"])
                # the drawn point is the truth's formula of the same coordinates: rounding of lengths of order 0.1 m
                np.testing.assert_allclose([pin.get_xdata()[0], pin.get_ydata()[0]], p[k], atol=1e-12)


def test_the_slider_crank_paths_are_the_crank_circle_and_the_guide_line():
    mech = load(api.example("slider_crank"), analysis={"steps": STEPS})
    results = api.solve(mech)
    sc = scene(results, mech)
    assert set(sc.outlines) == {"crank", "connecting_rod", "slider"} and sc.anchors == [(0.0, 0.0)]
    radii = [np.hypot(*path.T) for _, path in sc.paths]
    # geometry of lengths of order 0.1 m: rounding
    circle = [r for r in radii if np.allclose(r, 0.1, atol=1e-12)]
    assert len(circle) == 1  # the crank pin, drawn once though it is on two bodies
    line = [path for _, path in sc.paths if np.allclose(path[:, 1], 0.0, atol=1e-12)]
    assert len(line) == 1 and np.ptp(line[0][:, 0]) == pytest.approx(0.2)  # the stroke is 2 L_crank
    assert [s[0] for s in sc.slots] == ["cylinder_guide"] and sc.slots[0][3]


@pytest.mark.parametrize("name", ["quick_return", "slider_pendulum", "slider_crank"])
def test_every_slot_holds_its_pin_at_every_instant(name):
    mech = load(api.example(name), analysis={"steps": STEPS})
    results = api.solve(mech)
    truth = Truth(mech, results)
    sc = scene(results, mech)
    assert sc.slots
    for slot, start, end, _ in sc.slots:
        c = next(c for c in mech.constraints if c.name == slot)
        pin, _ = truth.point(c.bodies["j"], c.values["sj"])
        along = end - start
        s = np.sum((pin - start) * along, 1) / np.sum(along * along, 1)
        off = np.abs(along[:, 0] * (pin - start)[:, 1] - along[:, 1] * (pin - start)[:, 0])
        assert np.all((0.05 < s) & (s < 0.95)), slot  # inside, with a margin at each end
        assert np.max(off / np.hypot(*along.T)) < 1e-9, slot  # on the line


def test_planetary_gears_are_drawn_with_their_pitch_radii():
    mech = load(api.example("planetary"), analysis={"steps": 9})
    sc = scene(api.solve(mech), mech)
    radii = {(body, round(r, 12)) for body, _, r, _ in sc.gears}
    assert radii == {("sun", 0.03), ("planet", 0.03), ("ground", 0.09), ("input_pinion", 0.02)}


def test_an_eccentric_gears_pitch_circle_turns_about_its_axis_not_its_centre_of_mass():
    """The small gear pair with both centres of mass off their bearings: each
    pitch circle is centred on its bearing's point at every instant (the
    joint's point, from the table's q), radii 0.05 and 0.1 as in the file."""
    from small_mechanisms import CONSTRAINTS, text

    gears = (CONSTRAINTS["gears"].replace('"pinion"\nmass = 0.2\ninertia = 0.0004\nq0 = [0.0, 0.0, 0.0]',
                                          '"pinion"\nmass = 0.2\ninertia = 0.0004\nq0 = [0.01, 0.0, 0.0]')
             .replace('"wheel"\nmass = 0.8\ninertia = 0.009\nq0 = [0.15, 0.0, 0.0]',
                      '"wheel"\nmass = 0.8\ninertia = 0.009\nq0 = [0.17, 0.0, 0.0]'))
    gears = gears.replace('j = "pinion"\nsi = [0.0, 0.0]\nsj = [0.0, 0.0]', 'j = "pinion"\nsi = [0.0, 0.0]\nsj = [-0.01, 0.0]')
    gears = gears.replace('j = "wheel"\nsi = [0.15, 0.0]\nsj = [0.0, 0.0]', 'j = "wheel"\nsi = [0.15, 0.0]\nsj = [-0.02, 0.0]')
    assert gears.count("-0.01, 0.0]") == 1 and gears.count("-0.02, 0.0]") == 1 and "0.17" in gears
    mech = loads(text("eccentric", gears), "eccentric.toml")
    results = api.solve(mech)
    truth = Truth(mech, results)
    drawn = {body: (centre, radius) for body, centre, radius, _ in scene(results, mech).gears}
    for body, bearing, radius in (("pinion", "bearing1", 0.05), ("wheel", "bearing2", 0.1)):
        c = next(c for c in mech.constraints if c.name == bearing)
        axis, _ = truth.point(body, c.values["sj"])
        com, _ = truth.point(body, (0, 0))
        assert np.max(np.hypot(*(com - axis).T)) > 0.009  # the centre of mass is elsewhere
        # geometry of lengths of order 0.1 m: rounding
        np.testing.assert_allclose(drawn[body][0], axis, atol=1e-12)
        assert drawn[body][1] == pytest.approx(radius, rel=1e-12)


def test_springs_are_drawn_between_their_points():
    mech = load(api.example("four_bar"), analysis={"steps": 9})
    results = api.solve(mech)
    fig = plot.mechanism_figure(results, mech)
    spring = lines(fig, "spring:")["spring:rocker_return_spring"]
    truth = Truth(mech, results)
    rocker_end, _ = truth.point("rocker", (sp.Float(0.05), sp.Integer(0)))
    ends = np.array([[spring.get_xdata()[0], spring.get_ydata()[0]], [spring.get_xdata()[-1], spring.get_ydata()[-1]]])
    k = int(spring.axes.get_gid().split(":")[1])
    # geometry of lengths of order 0.1 m: rounding
    np.testing.assert_allclose(ends, [[0.75, 0.30], rocker_end[k]], atol=1e-12)


def test_the_gif_has_one_frame_per_instant_asked_for(tmp_path):
    mech = load(api.example("slider_crank"), analysis={"steps": 25})
    path = plot.write_gif(api.solve(mech), mech, tmp_path / "motion.gif", frames=6)
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.n_frames == 6  # a full revolution: t1 repeats t0, left out
        assert 300 <= gif.size[0] <= 800
    assert [p.name for p in tmp_path.iterdir()] == ["motion.gif"]


def test_plot_command_reads_a_csv_and_draws_from_the_mechanism(tmp_path, capsys):
    example = str(api.example("slider_crank"))
    assert main(["solve", example, "-o", str(tmp_path / "run.csv"), "--steps", "21"]) == 0
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "run.csv"), "--mechanism", example, "-o", str(tmp_path / "img")]) == 0
    printed = capsys.readouterr().out.split()
    assert printed == [str(tmp_path / "img" / f"run_{w}.png") for w in ("efforts", "reactions", "mechanism")]


def test_plot_command_without_the_mechanism_draws_reactions_and_says_what_it_skipped(tmp_path, capsys):
    assert main(["solve", str(api.example("four_bar")), "-o", str(tmp_path / "run.npz"), "--steps", "11"]) == 0
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "run.npz")]) == 0
    out, err = capsys.readouterr()
    assert out.split() == [str(tmp_path / "run_reactions.png")]
    assert "skipped the efforts plot: needs the mechanism file" in err


def test_plot_command_refuses_results_of_another_mechanism(tmp_path, capsys):
    assert main(["solve", str(api.example("four_bar")), "-o", str(tmp_path / "run.csv"), "--steps", "5"]) == 0
    status = main(["plot", str(tmp_path / "run.csv"), "--mechanism", str(api.example("slider_crank"))])
    err = capsys.readouterr().err
    assert status == 2 and "run.csv: column 'coupler.x' names nothing in" in err and "\n" == err[-1]


def test_a_table_without_instants_is_skipped_with_a_reason(tmp_path, capsys):
    mech = load(api.example("slider_crank"), analysis={"steps": 3})
    header = ",".join(api.solve(mech).columns)
    (tmp_path / "failed.csv").write_text(header + "\n")
    assert main(["plot", str(tmp_path / "failed.csv"), "--mechanism", str(api.example("slider_crank"))]) == 0
    out, err = capsys.readouterr()
    assert out == "" and err == "symid plot: skipped the plots: the table has no instants\n"


def test_solve_plot_writes_the_pngs_beside_the_table(tmp_path, capsys):
    out = tmp_path / "sc.csv"
    assert main(["solve", str(api.example("slider_crank")), "-o", str(out), "--steps", "21", "--plot"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "sc.csv", "sc_efforts.png", "sc_mechanism.png", "sc_reactions.png"]
    assert "motor: peak torque" in capsys.readouterr().out


def test_solving_without_plots_never_imports_matplotlib(tmp_path):
    code = ("import sys; from symid.cli import main; "
            f"main(['solve', {str(api.example('slider_crank'))!r}, '-o', {str(tmp_path / 'a.csv')!r}, "
            "'--steps', '5']); print('matplotlib' in sys.modules)")
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, check=True)
    assert run.stdout.strip().splitlines()[-1] == "False"
