"""`symid optimize` on the sizing figures (#29, point 6): a drive's verdict
bounded as `D.fits>=1` through its checks' margins (their exact gradients
against central differences of the verdict itself), a bearing's life bounded
below, and what is refused (one line, exit 2, before any solve).

The optimizations run on the upright slider-crank with a counterweight
(`slider_crank_counterweight`) given a small motor at 1:1 and a bearing on its
main pin: a heavier counterweight lowers the motor's torque and loads the pin,
so bounding one while minimizing the other leaves the bound active."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.io.reader import loads
from symid.model.mechanism import parameter_symbol
from symid.model.params import parameter_values
from symid.output.results import columns
from symid.output.sizing import load_of
from symid.output.sizing.motor import motor_of, verdict
from symid.study import optimize as opt
from symid.study.figures import figure_names
from symid.study.gradients import drive_margins, figure_gradients, needed_columns
from symid.study.slow import solve_variant, study_analysis, with_values
from symid.symbolic.assemble import assemble
from symid.tools.sensitive import solver

# the counterweight's crank with a 0.6 N m continuous motor at 1:1 and a
# bearing of C = 400 N on its main pin (a small one: lives of 1e5 to 1e6 h)
DRIVE = """
[[drive]]
driver = "motor"
ratio = 1.0
rotor_inertia = 0.0
efficiency = 1.0
continuous_torque = 0.6
peak_torque = 3.0
max_speed = 100.0
"""


@pytest.fixture(scope="module")
def counterweight(tmp_path_factory) -> Path:
    text = api.example("slider_crank_counterweight").read_text(encoding="utf-8")
    pin = 'name = "main_bearing"\ntype = "revolute"\n'
    assert pin in text and "\nsteps = 201" in text
    text = text.replace(pin, pin + "bearing = { C = 400.0, p = 3 }\n").replace("\nsteps = 201", "\nsteps = 11")
    path = tmp_path_factory.mktemp("sizing") / "counterweight_sized.toml"
    path.write_text(text + DRIVE, encoding="utf-8")
    return path


def size(path: Path, capsys, *args: str) -> tuple[int, dict]:
    status = main(["size", str(path), "--backend", "numpy", "--json", *args])
    return status, json.loads(capsys.readouterr().out)


def test_fits_bound_lands_on_a_design_that_symid_size_says_fits(counterweight, tmp_path, capsys, monkeypatch):
    """From m_cw = 0.2 (RMS 1.36 N m: does not fit, exit 4), minimizing the
    main pin's peak force (which a lighter counterweight lowers) under
    motor.fits>=1 ends where the RMS check is just met: `symid size` exits 0
    there, its RMS at the continuous 0.6 N m (active, to 1e-6)."""
    status, start = size(counterweight, capsys, "--set", "m_cw=0.2")
    assert status == 4 and not start["drives"][0]["fits"]
    monkeypatch.chdir(tmp_path)
    assert main(["optimize", str(counterweight), "--minimize", "main_bearing.force_peak", "--vary", "m_cw=0:4",
                 "--set", "m_cw=0.2", "--subject-to", "motor.fits>=1", "--backend", "numpy", "-o", "best.toml"]) == 0
    out = capsys.readouterr().out
    assert "motor.fits = 1 (>= 1)" in out, out
    m_cw = tomllib.loads((tmp_path / "best.toml").read_text())["parameters"]["m_cw"]
    status, end = size(counterweight, capsys, "--set", f"m_cw={m_cw!r}")
    drive = end["drives"][0]
    assert status == 0 and drive["fits"] and drive["why"] == [], drive
    assert drive["motor_rms"] == pytest.approx(0.6, rel=1e-6)  # active: the force wants m_cw lower
    assert 0.2 < m_cw < 4


def test_fits_bound_that_cannot_be_met_is_exit_3_naming_the_failed_check(counterweight, tmp_path, capsys,
                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["optimize", str(counterweight), "--minimize", "main_bearing.force_peak", "--vary", "m_cw=0:0.5",
                 "--set", "m_cw=0.2", "--subject-to", "motor.fits>=1", "--backend", "numpy", "-o", "best.toml"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "motor.fits = 0 (>= 1: RMS torque margin -" in err, err
    assert not (tmp_path / "best.toml").exists()


def test_life_bound_is_met_and_active(counterweight):
    """Minimizing the motor's RMS torque wants a heavy counterweight; the main
    pin's life >= 1e6 h holds it back: the optimum meets the bound to 1e-6
    (SLSQP's feasibility at ftol 1e-14: far below), from a start below it."""
    mech = with_values(api.load_mechanism(counterweight), ["m_cw"], [0.2])
    limit = opt.Limit("main_bearing.L10_h", ">=", 1e6)
    problem = opt.Problem(mech, "motor.effort_rms", opt.parse_vary(["m_cw=0:4"]), [limit], solver("numpy"))
    assert problem.value((problem.start - problem.lo) / problem.width, limit.figure) < 1e6  # the start misses it
    out = opt.run(problem)
    assert out.success and not out.unmet, (out.message, out.unmet)
    life = problem.value((out.p - problem.lo) / problem.width, limit.figure)
    assert life == pytest.approx(1e6, rel=1e-6) and life >= 1e6 * (1 - 1e-9)
    assert 0.05 < out.p[0] < 0.2  # lighter than the start: the life bound, not a range bound, stops it


# A flywheel swung by theta = A sin(w t) against a weight F0 on an arm (a load
# torque that does not scale with A, so the best ratio of [1, 100] moves with
# both parameters), motoring and back-driven, with a corner speed the worst
# operating point is past: every term of the margins' gradients is at work.
SWING = """
[mechanism]
name = "swing"
gravity = [0.0, -9.81]
[parameters]
A = 0.8
w = "2*pi"
F0 = 40.0
[analysis]
t1 = 1.0
steps = 41
[[body]]
name = "wheel"
mass = 2.0
inertia = 0.05
q0 = [0.0, 0.0, 0.0]
[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "wheel"
si = [0.0, 0.0]
sj = [0.0, 0.0]
[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "wheel"
f = "A*sin(w*t)"
[[force]]
name = "weight"
type = "point_force"
body = "wheel"
s = [0.1, 0.0]
F = [0.0, "-F0"]
"""
SWING_DRIVE = """
[[drive]]
driver = "motor"
ratio = [1.0, 100.0]
efficiency = 0.8
back_efficiency = 0.7
rotor_inertia = 2e-4
continuous_torque = 0.3
peak_torque = 0.6
max_speed = 200.0
corner_speed = 60.0
"""
# the same drive's own values as parameters (a fixed ratio k; a range whose
# best ratio sits on its upper bound hi): the derivatives through them
SWING_PARAMETERS = {"k": 30.0, "hi": 10.0, "eta": 0.8, "eta_b": 0.7, "J_m": 2e-4, "T_c": 0.3, "T_p": 0.6,
                    "w_max": 200.0, "w_c": 20.0}
SWING_DRIVE_OF_PARAMETERS = """
[[drive]]
driver = "motor"
ratio = RATIO
efficiency = "eta"
back_efficiency = "eta_b"
rotor_inertia = "J_m"
continuous_torque = "T_c"
peak_torque = "T_p"
max_speed = "w_max"
corner_speed = "w_c"
"""


def _verdict(mech):
    values = parameter_values(mech.parameters)
    load, _, _ = load_of(mech, solve_variant(mech, "numpy"), "motor", values)
    return verdict(load, motor_of(mech.sizing.drives[0], values))


def test_fit_margins_and_motor_peak_gradients_match_central_differences_of_the_verdict():
    """d/dP of `Verdict.margins` (RMS, peak, speed, worst envelope point) and of
    motor_peak against central differences of the verdict (h = 1e-6 P:
    truncation ~1e-12, rounding ~1e-10 relative: held to 1e-7)."""
    names = ["A", "F0"]
    mech = study_analysis(loads(SWING + SWING_DRIVE, "swing.toml"))
    results = solver("numpy")(mech, names, needed_columns(mech, columns(assemble(mech), mech.analysis)))
    margins, grads = drive_margins(mech, results, names, ["motor"])["motor"]
    peak = figure_gradients(mech, results, names)[figure_names(mech).index("motor.motor_peak")]
    v = _verdict(mech)
    np.testing.assert_allclose(margins, v.margins(), rtol=1e-12)
    assert v.fits and np.all(v.margins() > 0)
    k = int(np.argmin(v.motor.available(v.speed) - np.abs(v.torque)))
    assert abs(v.speed[k]) > 60.0 and v.motor.slope(v.speed[k]) < 0  # the worst point is past the corner
    values = parameter_values(mech.parameters)
    for j, name in enumerate(names):
        p = values[parameter_symbol(name)]
        h = 1e-6 * p
        up, down = _verdict(with_values(mech, [name], [p + h])), _verdict(with_values(mech, [name], [p - h]))
        assert abs(up.ratio - down.ratio) > 1e-7 * v.ratio  # the best ratio moves with the parameter
        np.testing.assert_allclose(grads[:, j], (up.margins() - down.margins()) / (2 * h), rtol=1e-7, atol=1e-9)
        assert peak[j] == pytest.approx((up.motor_peak - down.motor_peak) / (2 * h), rel=1e-7), name


@pytest.mark.parametrize("ratio", ['"k"', '[1.0, "hi"]'])
def test_margin_gradients_through_the_drives_own_values_match_central_differences(ratio):
    """Ratio (fixed, or the upper bound its best sits on), efficiencies, rotor
    inertia and ratings as parameters: d/dP of the margins and of motor_rms,
    motor_peak against central differences of the verdict (as above)."""
    head = SWING.replace("F0 = 40.0\n", "F0 = 40.0\n" + "".join(f"{n} = {v!r}\n" for n, v in SWING_PARAMETERS.items()))
    mech = study_analysis(loads(head + SWING_DRIVE_OF_PARAMETERS.replace("RATIO", ratio), "swing.toml"))
    names = [n for n in SWING_PARAMETERS if n != ("hi" if ratio == '"k"' else "k")]
    results = solver("numpy")(mech, names, needed_columns(mech, columns(assemble(mech), mech.analysis)))
    margins, grads = drive_margins(mech, results, names, ["motor"])["motor"]
    figures = figure_gradients(mech, results, names)
    at = [figure_names(mech).index(f"motor.motor_{f}") for f in ("rms", "peak")]
    v = _verdict(mech)
    assert v.ratio == (30.0 if ratio == '"k"' else 10.0)
    k = int(np.argmin(v.motor.available(v.speed) - np.abs(v.torque)))
    assert abs(v.speed[k]) > 20.0  # past the corner: the corner and max speed move the envelope there
    for j, name in enumerate(names):
        p = SWING_PARAMETERS[name]
        h = 1e-6 * p
        up, down = _verdict(with_values(mech, [name], [p + h])), _verdict(with_values(mech, [name], [p - h]))
        central = (up.margins() - down.margins()) / (2 * h)
        np.testing.assert_allclose(grads[:, j], central, rtol=1e-6, atol=1e-9 / p, err_msg=name)
        for i, f in zip(at, ("motor_rms", "motor_peak")):
            assert figures[i, j] == pytest.approx((getattr(up, f) - getattr(down, f)) / (2 * h), rel=1e-6,
                                                  abs=1e-12 / p), (name, f)


def test_margins_say_what_the_verdict_says():
    """Each margin negative exactly when its check fails (the RMS just over, the peak just under)."""
    v = _verdict(loads(SWING + SWING_DRIVE.replace("continuous_torque = 0.3", "continuous_torque = 0.2"),
                       "swing.toml"))
    m = v.margins()
    assert not v.fits and m[0] < 0 and np.all(m[1:] > 0) and v.why[0].startswith("RMS torque")
    assert m[0] == pytest.approx(1 - v.motor_rms / 0.2, rel=1e-12)


CRANK = str(api.example("slider_crank"))
SIZED = str(api.example("slider_crank_sized"))
RMS = ["--minimize", "motor.motor_rms", "--vary", "n=4:6"]
BAD = {
    "minimize_a_verdict": ([SIZED, "--minimize", "motor.fits", "--vary", "n=4:6"],
                           "--minimize motor.fits: a verdict (1 or 0) is not minimized: bound it with "
                           "--subject-to motor.fits>=1"),
    "verdict_bounded_below_one": ([SIZED, *RMS, "--subject-to", "motor.fits>=0.5"],
                                  "a verdict (1 or 0) is bounded only as motor.fits>=1"),
    "verdict_bounded_above": ([SIZED, *RMS, "--subject-to", "motor.fits<=0.5"],
                              "--subject-to motor.fits<=0.5: a verdict (1 or 0) is bounded only as motor.fits>=1"),
    "minimize_a_life": ([SIZED, "--minimize", "main_bearing.L10_h", "--vary", "n=4:6"],
                        "a life is wanted long, and symid optimize minimizes (maximizing is not in the command "
                        "line): bound it with --subject-to main_bearing.L10_h>=HOURS"),
    "life_of_a_file_without_bearings": ([CRANK, "--minimize", "motor.effort_rms", "--vary", "n=4:6",
                                         "--subject-to", "crank_pin.L10_h>=20000"],
                                        "no figure 'crank_pin.L10_h' (figures: motor.effort_peak"),
    "life_of_a_pin_without_bearing": ([SIZED, *RMS, "--subject-to", "wrist_pin.L10_h>=20000"],
                                      "a bearing's life needs bearing = { C = ..., p = ... } on its revolute"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sizing_figure_is_one_line_exit_2_before_any_solve(tmp_path, capsys, monkeypatch, case):
    import symid.tools.sensitive as sensitive

    def no_solve(backend: str):
        raise AssertionError("a bad input must be refused before any solve")

    monkeypatch.setattr(sensitive, "solver", no_solve)
    args, message = BAD[case]
    status = main(["optimize", *args, "--steps", "3", "-o", str(tmp_path / "out.toml")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
    assert not (tmp_path / "out.toml").exists()


def test_a_life_bound_and_the_verdict_bound_pass_the_checks():
    """What is accepted: D.fits>=1 and a life bounded either way (it has a gradient)."""
    mech = api.load_mechanism(SIZED)
    bounds = opt.parse_vary(["n=4:6"])
    for spec in ("motor.fits>=1", "main_bearing.L10_h>=20000", "crank_pin.L10_h<=1e9"):
        opt.check(mech, "motor.motor_rms", bounds, opt.parse_limits([spec]))


def test_envelope_points_of_a_parameter_varied_stop_the_fits_bound_naming_them():
    """The one case without a gradient (exit 3 on the command line, nothing written)."""
    from symid.errors import AnalysisError

    drive = SWING_DRIVE.replace("corner_speed = 60.0", 'envelope = [[0.0, 0.6], ["w_e", 0.3], [200.0, 0.0]]')
    mech = loads(SWING.replace("F0 = 40.0\n", "F0 = 40.0\nw_e = 100.0\n") + drive, "swing.toml")
    problem = opt.Problem(mech, "motor.motor_rms", opt.parse_vary(["w_e=50:150"]),
                          opt.parse_limits(["motor.fits>=1"]), solver("numpy"))
    with pytest.raises(AnalysisError, match=r"the envelope margin of motor.fits>=1 has no gradient by w_e \(nan\): "
                                            "an envelope whose points depend on a parameter varied has none"):
        opt.run(problem)
