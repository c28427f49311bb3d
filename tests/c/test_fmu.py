"""`symid generate --target fmu` (issue #30 point 5): an FMI 2.0 model-exchange
FMU of the set-point entry, loaded and simulated by FMPy (an independent
importer), against `symid solve`: with the inputs set to the motion laws'
set-points at the output times (sympy, from the file), every output matches
the solved column to 1e-12 of its peak. FMPy's own validation passes. Faults
of the compiler are one line, exit status 2."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.io.reader import load, loads
from setpoints import PENDULUM, Laws, expression_drivers, laws
from tiers import first_quick

fmpy = pytest.importorskip("fmpy", reason="FMPy is the test extra's FMI importer (pip install fmpy)")
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
ROOT = Path(__file__).resolve().parents[2]
GROUPS = {"lambda": ".lambda", "reactions": (".Fx", ".Fy", ".T")}


def _fmu(example: str, folder: Path, text: str | None = None) -> Path:
    """The FMU of a bundled example (or of a mechanism file's text)."""
    written = api.generate(loads(text, f"{example}.toml") if text else api.example(example), "fmu", folder)
    assert [p.name for p in written] == [f"{example}.fmu"]
    return written[0]


def _column_peaks(results, columns: list[str]) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Each column's peak, or 1e-3 of its group's peak for a column that is
    zero but for rounding (the README's rule for comparing columns)."""
    def group(c: str) -> str:
        tail = c.rsplit(".", 1)[1]
        return "lambda" if tail.startswith("lambda") else "reactions" if "_" in tail else tail
    peaks = {c: float(np.max(np.abs(results[c]))) for c in columns}
    group_peak: dict[str, float] = {}
    for c, v in peaks.items():
        group_peak[group(c)] = max(group_peak.get(group(c), 0.0), v)
    return {c: max(v, 1e-3 * group_peak[group(c)], 1e-300) for c, v in peaks.items()}


def _check_against_solve(example: str, folder: Path, text: str | None = None) -> float:
    """The FMU against symid solve; returns the worst error, of its column's peak."""
    from fmpy import read_model_description, simulate_fmu
    from fmpy.validation import validate_fmu

    path = _fmu(example, folder, text)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    mech = loads(text, f"{example}.toml") if text else load(api.example(example))
    a = mech.analysis
    solved = api.solve(mech)
    assert solved.error is None
    h = (a.t1 - a.t0) / (a.steps - 1)
    times = a.t0 + h * np.arange(a.steps)  # FMPy's output points: start + n * interval
    signals = np.zeros(a.steps, dtype=[("time", float)] + [(n, float) for n in inputs])
    signals["time"] = times
    velocity = a.kind != "statics"
    law = Laws(mech)
    for k, t in enumerate(times):
        f, fd, fdd = law(float(t))
        values = np.stack([f, fd, fdd], axis=1)[:, :3 if velocity else 1].ravel()  # per driver q, qd, qdd
        for n, v in zip(inputs, values):
            signals[n][k] = v
    result = simulate_fmu(str(path), start_time=a.t0, stop_time=a.t1, solver="Euler", step_size=h,
                          output_interval=h, input=signals, output=outputs)
    assert len(result) == a.steps
    assert np.allclose(result["time"], solved.t, rtol=0, atol=1e-12 * max(1.0, abs(a.t1)))
    assert set(outputs) <= set(solved.columns)
    peaks = _column_peaks(solved, outputs)
    worst = max(outputs, key=lambda c: np.max(np.abs(result[c] - solved[c])) / peaks[c])
    error = np.max(np.abs(result[worst] - solved[worst])) / peaks[worst]
    # the same equations solved in C (the FMU) and by the numpy backend:
    # rounding, carried by the conditioning of the bigger mechanisms
    assert error <= 1e-12, (example, worst, error)
    return float(error)


@needs_cc
def test_fmu_validates_and_matches_solve_on_the_slider_crank(tmp_path: Path) -> None:
    _check_against_solve("slider_crank", tmp_path)


@needs_cc
@pytest.mark.slow
@pytest.mark.parametrize("example", [e for e in api.examples() if e != "slider_crank"])
def test_fmu_validates_and_matches_solve_on_every_example(tmp_path: Path, example: str) -> None:
    _check_against_solve(example, tmp_path)


@needs_cc
@pytest.mark.parametrize("example", first_quick(["four_bar", "slider_pendulum"]))
def test_fmu_takes_an_expression_driver_as_inputs_and_matches_solve(tmp_path: Path, example: str) -> None:
    """The examples' angle drivers written as expression rows g(q) - f(t):
    each is a driver whose three set-points are inputs (the slider
    pendulum's after its carriage's translational driver, by row)."""
    from fmpy import read_model_description

    text = expression_drivers(api.example(example).read_text())
    _check_against_solve(example, tmp_path, text)
    md = read_model_description(str(tmp_path / f"{example}.fmu"))
    inputs = {v.name: v.description for v in md.modelVariables if v.causality == "input"}
    motor = next(c.name for c in loads(text, "m.toml").constraints if c.type == "expression" and "f" in c.values)
    assert list(inputs)[-3:] == [f"{motor}.{s}" for s in ("q_des", "qd_des", "qdd_des")]
    assert inputs[f"{motor}.q_des"] == "set-point: the value of f of its row g(q) - f(t)"


@needs_cc
@pytest.mark.parametrize("kind", ["statics", "kinematics"])
def test_fmu_of_statics_and_kinematics_matches_solve(tmp_path: Path, kind: str) -> None:
    """Statics: q_des the only inputs, q and the multipliers out;
    kinematics: q and its rates, no multipliers."""
    _check_against_solve("pendulum_ct", tmp_path, PENDULUM.replace("[analysis]\n", f'[analysis]\nkind = "{kind}"\n'))


@needs_cc
def test_fmu_holds_sources_and_model_description_and_takes_tunable_parameters(tmp_path: Path) -> None:
    """The archive's layout; a parameter set through FMI changes the outputs
    as the same parameter changes symid solve's (--set)."""
    from fmpy import read_model_description, simulate_fmu

    path = _fmu("slider_crank", tmp_path)
    names = zipfile.ZipFile(path).namelist()
    assert "modelDescription.xml" in names and any(n.startswith("binaries/") for n in names)
    assert {f"sources/slider_crank_{f}" for f in ("solver.c", "solver.h", "fmi2.c")} <= set(names)
    md = read_model_description(str(path))
    m = next(v for v in md.modelVariables if v.name == "m_slider")
    assert (m.causality, m.variability) == ("parameter", "tunable")
    mech = load(api.example("slider_crank"), {"m_slider": "3.0"})
    solved = api.solve(mech)
    a = mech.analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    times = a.t0 + h * np.arange(a.steps)
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    signals = np.zeros(a.steps, dtype=[("time", float)] + [(n, float) for n in inputs])
    signals["time"] = times
    law = Laws(mech)
    for k, t in enumerate(times):
        for n, v in zip(inputs, np.stack(law(float(t)), axis=1).ravel()):
            signals[n][k] = v
    result = simulate_fmu(str(path), start_time=a.t0, stop_time=a.t1, solver="Euler", step_size=h, output_interval=h,
                          input=signals, start_values={"m_slider": 3.0}, output=["motor.lambda"])
    peak = np.max(np.abs(solved["motor.lambda"]))
    assert np.max(np.abs(result["motor.lambda"] - solved["motor.lambda"])) <= 1e-12 * peak


def _generate(tmp_path: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "symid", "generate", str(api.example("slider_crank")),
                           "--target", "fmu", "-o", str(tmp_path / "out")],
                          capture_output=True, text=True, env=env, cwd=tmp_path)


@pytest.mark.parametrize("case", first_quick(["no compiler", "CC not found", "CC fails"]))  # one fault, one path
def test_compiler_faults_are_one_line_and_exit_2_with_nothing_written(tmp_path: Path, case: str) -> None:
    env = {k: v for k, v in os.environ.items() if k != "CC"}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    if case == "no compiler":
        empty = tmp_path / "bin"
        empty.mkdir()
        env["PATH"] = str(empty)
    elif case == "CC not found":
        env["CC"] = str(tmp_path / "no-such-cc")
    else:
        env["CC"] = "false"  # runs, fails, says nothing
    run = _generate(tmp_path, env)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in run.stderr, run.stderr
    assert "--target fmu" in lines[0] and ("compiler" in lines[0]), lines[0]
    assert not (tmp_path / "out" / "slider_crank.fmu").exists()


@needs_cc
def test_fmu_reads_time_when_only_time_changes(tmp_path: Path, tmp_path_factory) -> None:
    """An importer may advance time without setting unchanged inputs: the
    four-bar's coupler load F_tool (1 + 0.5 sin(omega t)) moves the efforts
    then, as the generated C's _setpoint at that time gives them (the
    set-points held at those of t1)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Model
    from setpoints import Solver

    path = _fmu("four_bar", tmp_path / "fmu")
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    model = FMU2Model(guid=md.guid, unzipDirectory=extract(str(path), str(tmp_path / "unzipped")),
                      modelIdentifier=md.modelExchange.modelIdentifier, instanceName="four_bar")
    model.instantiate()
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    model.enterContinuousTimeMode()
    solver = Solver(api.example("four_bar"), tmp_path / "c", share=tmp_path_factory)  # the export's object
    t1, t2 = 0.05, 0.3
    des = laws(solver.mech, t1)
    model.setTime(t1)
    model.setReal([vr[n] for n in inputs], list(np.stack(des, axis=1).ravel()))
    first = np.array(model.getReal([vr[n] for n in outputs]))
    model.setTime(t2)  # the inputs unchanged
    second = np.array(model.getReal([vr[n] for n in outputs]))
    model.terminate()
    model.freeInstance()
    status, out = solver.call("setpoint", t2, first[:solver.ng], des)
    assert status == 0
    lam = [k for k, n in enumerate(outputs) if n.endswith(".lambda") or ".lambda" in n]
    expected = out["lam"]
    assert np.max(np.abs(second[lam] - expected)) <= 1e-12 * np.max(np.abs(expected))
    assert np.max(np.abs(second[lam] - first[lam])) > 1e-3 * np.max(np.abs(expected))  # the load moved them


@needs_cc
def test_a_set_point_the_solver_refuses_is_an_fmi2_error_logged_with_time_and_status(tmp_path: Path, capfd) -> None:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Model, fmi2Error
    from fmpy.fmi1 import FMICallException

    path = _fmu("slider_crank", tmp_path / "fmu")
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    model = FMU2Model(guid=md.guid, unzipDirectory=extract(str(path), str(tmp_path / "unzipped")),
                      modelIdentifier=md.modelExchange.modelIdentifier, instanceName="sc")
    model.instantiate(loggingOn=True)  # FMPy's default logger prints each message
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    model.enterContinuousTimeMode()
    model.setTime(0.01)
    model.setReal([vr["motor.q_des"]], [float("nan")])
    with pytest.raises(FMICallException) as raised:
        model.getReal([vr["motor.lambda"]])
    assert raised.value.status == fmi2Error
    model.freeInstance()
    said = capfd.readouterr().out
    assert "t = 0.01" in said and "an input or parameter is not finite (status 5)" in said, said
