"""Driver efforts, their power and the summary lines, against physics the
summary does not use: reaction forces along the actuator, the energy balance,
the table's velocity columns, and closed forms for peak and RMS."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api

from symid.output import summary
from symid.cli import main
from symid.io.reader import load
from symid.output.results import Results
from truth import Truth

EXAMPLES = api.examples()
STEPS = 41


@pytest.fixture(scope="module", params=EXAMPLES)
def solved(request):
    mech = load(api.example(request.param), analysis={"steps": STEPS})
    results = api.solve(mech)
    assert results.error is None, results.error
    return mech, results


def test_every_driver_of_every_example_has_an_effort(solved):
    mech, results = solved
    found = summary.efforts(mech, results)
    assert [e.name for e in found] == [c.name for c in summary.drivers(mech)]
    for e in found:
        assert e.value.shape == e.rate.shape == results.t.shape
        assert np.all(np.isfinite(e.value)) and np.any(e.value != 0)


def test_driver_power_is_the_rate_of_kinetic_energy_less_applied_power(solved):
    """Ideal joints do no work, so the drivers' power (effort x rate, summed)
    is dT/dt minus the power of gravity, forces and springs (and of joint
    friction, which the friction columns give)."""
    mech, results = solved
    truth = Truth(mech, results)
    lost = sum((results[f"{c.name}.friction_power"] for c in mech.constraints if c.friction), 0.0)
    expected = truth.kinetic_power() - truth.load_power(truth.applied_loads()) - lost
    total = sum(e.power for e in summary.efforts(mech, results))
    scale = np.max(np.abs(expected)) + np.max(np.abs(truth.load_power(truth.applied_loads())))
    # the power balance sums products of rates and loads: 1e-8 of the largest power
    assert np.max(np.abs(total - expected)) < 1e-8 * scale


def test_motor_torque_is_the_T_j_column_and_its_power_uses_the_relative_speed():
    mech = load(api.example("slider_crank"), analysis={"steps": STEPS})
    results = api.solve(mech)
    (motor,) = summary.efforts(mech, results)
    assert (motor.quantity, motor.unit) == ("torque", "N·m")
    np.testing.assert_array_equal(motor.value, results["motor.T_j"])
    # the product of two tabled columns, computed the same way: rounding
    np.testing.assert_allclose(motor.power, results["motor.T_j"] * results["crank.omega"], rtol=1e-9, atol=1e-9)


def test_cylinder_force_is_the_reaction_on_j_along_the_cylinder_pushing_apart():
    mech = load(api.example("excavator"), analysis={"steps": STEPS})
    results = api.solve(mech)
    truth = Truth(mech, results)
    for e in summary.efforts(mech, results):
        c = next(c for c in mech.constraints if c.name == e.name)
        pi, _ = truth.point(c.bodies["i"], c.values["si"])
        pj, _ = truth.point(c.bodies["j"], c.values["sj"])
        u = (pj - pi) / np.linalg.norm(pj - pi, axis=1)[:, None]
        on_j = np.stack([results[f"{e.name}.Fx_j"], results[f"{e.name}.Fy_j"]], 1)
        # the force along the actuator from its reactions: rounding relative (1e-9), 1e-6 N absolute where it crosses zero
        np.testing.assert_allclose(e.value, np.sum(on_j * u, 1), rtol=1e-9, atol=1e-6)
    # Holding the boom up against gravity, the boom cylinder pushes at t0.
    assert summary.efforts(mech, results)[0].value[0] > 0


def test_slide_force_is_the_reaction_on_j_along_the_slide_direction():
    mech = load(api.example("slider_pendulum"), analysis={"steps": STEPS})
    results = api.solve(mech)
    e = next(e for e in summary.efforts(mech, results) if e.type == "translational_driver")
    alpha = 10 * np.pi / 180  # the guide's inclination in the file
    on_j = np.stack([results[f"{e.name}.Fx_j"], results[f"{e.name}.Fy_j"]], 1)
    # the force along the guide from its reactions: rounding
    np.testing.assert_allclose(e.value, on_j @ [np.cos(alpha), np.sin(alpha)], rtol=1e-9, atol=1e-9)


def test_coordinate_driver_torque_is_its_T_i_column():
    mech = load(api.example("planetary"), analysis={"steps": STEPS})
    results = api.solve(mech)
    (e,) = summary.efforts(mech, results)
    assert (e.type, e.quantity) == ("coordinate_driver", "torque")
    np.testing.assert_array_equal(e.value, results["input_motor.T_i"])
    np.testing.assert_allclose(e.rate, 10 * np.pi)  # omega = 2 pi n_in, n_in = 5


def test_summary_peak_rms_and_peak_power_of_a_sine_over_one_period():
    t = np.linspace(0.0, 2.0, 401)
    e = summary.Effort("m", "relative_angle_driver", "torque", "N·m", "rad/s", "", t,
                       3 * np.sin(np.pi * t), np.full_like(t, 2.0))
    s = summary.summarize(e)
    assert s.peak == pytest.approx(3.0) and s.t_peak == pytest.approx(0.5)
    assert s.rms == pytest.approx(3 / np.sqrt(2), rel=1e-12)
    assert s.peak_power == pytest.approx(6.0)
    assert s.line() == ("m: peak torque 3 N·m at t = 0.5 s, RMS 2.121 N·m, "
                        "peak power 6 W at t = 0.5 s")


def test_peak_power_keeps_its_sign_when_the_motor_brakes():
    mech = load(api.example("slider_crank"), analysis={"steps": STEPS})
    results = api.solve(mech)
    s = summary.summarize(summary.efforts(mech, results)[0])
    power = results["motor.T_j"] * results["crank.omega"]
    k = int(np.argmax(np.abs(power)))
    assert s.peak_power == pytest.approx(power[k], rel=1e-9) and s.peak_power < 0
    assert f"peak power {s.peak_power:.4g} W" in s.line()


def test_summary_lines_say_which_driver_has_no_columns():
    mech = load(api.example("slider_crank"), analysis={"steps": 5, "outputs": ["q", "reactions"],
                                                       "reactions": ["main_bearing"]})
    (line,) = summary.lines(mech, api.solve(mech))
    assert line.startswith("motor: no effort") and "motor.T_j" in line


def test_a_kinematics_table_has_no_summary_lines():
    mech = load(api.example("slider_crank"), analysis={"steps": 5})
    full = api.solve(mech)
    kinematic = [c for c in full.columns if not c.rpartition(".")[2].startswith(("lambda", "F", "T_"))]
    table = Results(kinematic, full.block(kinematic))
    assert summary.lines(mech, table) == []


def test_recorder_passes_rows_through_and_keeps_the_chosen_columns():
    rows = [np.array([0.0, 1.0, 2.0]), np.array([1.0, 3.0, 4.0])]
    record = summary.Recorder(["t", "a.x", "b.x"], ["b.x", "t"])
    assert [r.tolist() for r in record(iter(rows))] == [r.tolist() for r in rows]
    kept = record.results()
    assert kept.columns == ["t", "b.x"]
    np.testing.assert_array_equal(kept["b.x"], [2.0, 4.0])


def test_solve_prints_one_summary_line_per_driver(tmp_path, capsys):
    out = tmp_path / "ex.csv"
    assert main(["solve", str(api.example("excavator")), "-o", str(out), "--steps", "21"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"{out}: 21 instants")
    assert [line.split(":")[0] for line in printed[1:]] == ["boom_cylinder", "stick_cylinder", "bucket_cylinder"]
    assert all(" N at t = " in line and " W at t = " in line for line in printed[1:])


def test_statics_prints_no_power_and_its_time_axis_says_what_t_is(tmp_path, capsys):
    """Statics has no speed: its lines have the effort's peak and RMS but no
    power, on the first run and on the planned (cached) one; its plots say
    that t only orders the equilibria. The inverse-dynamics line keeps it."""
    from symid.output import plot

    path = str(api.example("slider_crank_friction"))
    for _ in range(2):  # the second run may take the plan (no sympy): same lines
        assert main(["solve", path, "--kind", "statics", "--steps", "5", "-o", str(tmp_path / "s.csv")]) == 0
        out = capsys.readouterr().out.splitlines()
        assert out[1].startswith("motor: peak torque") and "RMS" in out[1], out
        assert not any("power" in line for line in out[1:]), out
    assert main(["solve", path, "--steps", "5", "-o", str(tmp_path / "d.csv")]) == 0
    assert ", peak power " in capsys.readouterr().out
    for kind, label in (("statics", plot.STATICS_TIME), ("inverse_dynamics", plot.TIME)):
        mech = load(api.example("slider_crank"), analysis={"steps": 5, "kind": kind})
        results = api.solve(mech)
        for fig in (plot.efforts_figure(results, mech), plot.reactions_figure(results, mech)):
            assert [ax.get_xlabel() for ax in fig.axes if ax.get_xlabel()] == [label]
    assert "no motion" in plot.STATICS_TIME and "time" not in plot.STATICS_TIME
