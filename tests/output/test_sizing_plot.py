"""The sizing picture (#29, point 5): the envelope drawn is the motor's
(peak to the corner speed, falling linearly to 0 at max_speed), the
trajectory and RMS point are the run's, the bars are the bearings' loads."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api
from symid.output import sizing
from symid.cli import main
from symid.output.sizing_plot import sizing_figure


def _line(fig, gid):
    found = [a for ax in fig.axes for a in ax.get_children() if a.get_gid() == gid]
    assert len(found) == 1, gid
    return found[0]


def test_envelope_trajectory_rms_point_and_bearing_bars():
    mech = sizing.for_sizing(api.load_mechanism(api.example("slider_crank_sized"), steps=41, **sizing.ANALYSIS))
    report = sizing.size(mech, api.solve(mech))
    fig = sizing_figure(report, mech.name)
    v = report.drives[0]
    w, torque = _line(fig, "envelope:motor").get_data()
    # the bundled servo: 1.91 N m to 314 rad/s, 0 at 628 (the file's comments)
    # drawn at 400 speeds: linear interpolation between them is exact on the straight pieces, 1e-2 at the corner
    assert np.interp([100.0, 314.0, 471.0, 628.0], w, torque) == pytest.approx([1.91, 1.91, 0.955, 0.0], abs=0.01)
    x, y = _line(fig, "trajectory:motor").get_data()
    np.testing.assert_array_equal(x, np.abs(v.speed))
    np.testing.assert_array_equal(y, np.abs(v.torque))
    _, rms = _line(fig, "rms:motor").get_data()
    assert rms[0] == v.motor_rms
    for b in report.bearings:
        bar = _line(fig, f"bearing:{b.joint}")  # the bar's rectangle carries the gid
        assert bar.get_height() == b.P_eq


def test_size_plot_writes_one_png(tmp_path, capsys):
    assert main(["size", str(api.example("slider_crank_sized")), "--plot", "-o", str(tmp_path)]) == 0
    assert [p.name for p in tmp_path.iterdir()] == ["slider_crank_sized_sizing.png"]
    assert (tmp_path / "slider_crank_sized_sizing.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
