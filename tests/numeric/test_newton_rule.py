"""One Newton rule (symid.numeric.newton) for the Python loop and both
generated loops: the templates are written from it, and every backend
applies its rounding floor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.codegen.model import code_model, options_for
from symid.codegen import c as c_target
from symid.codegen.c import compose as c_compose
from symid.codegen.targets import numpy_target
from symid.errors import AnalysisError
from symid.io.reader import loads
from symid.numeric import newton, solve

BACKENDS = ("numpy", "c", "casadi", "reference")

# A driven pendulum whose pivot is 1e7 m from the origin: a coordinate's last
# digit is worth 2e-9 m there, so tol = 1e-15 is reached only through the
# rule's rounding floor (8 ulps of max |q|: 1.8e-8 m).
FAR = """
[mechanism]
name = "far_pendulum"
gravity = [0, -9.81]
[analysis]
steps = 21
tol = 1e-15
[[body]]
name = "bar"
mass = 1.0
inertia = 0.1
q0 = [10000000.5, 0, 0]
[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "bar"
si = [10000000.0, 0]
sj = [-0.5, 0]
[[constraint]]
name = "drive"
type = "relative_angle_driver"
i = "ground"
j = "bar"
f = "sin(t)"
"""


def test_both_templates_are_written_from_the_rule(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mech = api.example("slider_crank")
    study = api.prepare(mech, "reference")
    model = code_model(study.mechanism, options_for(study.mechanism))
    changed = newton.NewtonRule(max_iterations=7, floor_ulps=16.0)
    for target in (c_compose, numpy_target):
        monkeypatch.setattr(target, "RULE", changed)
    c_target.generate(model, tmp_path / "c")
    numpy_target.generate(model, tmp_path / "numpy")
    c = (tmp_path / "c" / "slider_crank_solver.c").read_text()
    h = (tmp_path / "c" / "slider_crank_solver.h").read_text()  # the cap: an #ifndef default of the header
    py = (tmp_path / "numpy" / "slider_crank_solver.py").read_text()
    assert "#define SLIDER_CRANK_MAX_NEWTON 7\n" in h
    assert "#define SLIDER_CRANK_FLOOR_ULPS 16.0\n" in h  # the floor: the header's #ifndef default, read by
    assert "lim = SLIDER_CRANK_MAX(tol, ((slider_crank_real)SLIDER_CRANK_FLOOR_ULPS * SLIDER_CRANK_EPS) * qmag);" in c  # MISRA 12.1: explicit grouping, the same product
    assert "\nMAX_NEWTON = 7\n" in py
    assert "lim = max(tol, 16.0 * EPS * qmag)" in py


def test_the_python_loop_reads_the_rule() -> None:
    assert solve.MAX_NEWTON == newton.RULE.max_iterations
    assert newton.RULE.floor(1e7) == pytest.approx(8 * np.finfo(float).eps * 1e7)
    assert newton.EPS == np.finfo(float).eps


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_rounding_floor_lets_every_backend_converge_far_from_the_origin(backend: str) -> None:
    results = api.solve(loads(FAR, "far.toml"), backend=backend)
    assert results.error is None, results.error
    phi = np.sin(results.t)
    # the pendulum's angle against sin t: the run's tol and the floor of the rule, with room
    assert np.max(np.abs(results["bar.phi"] - phi)) < 1e-8
    # the motor holds the bar against gravity: T = -m g l cos(phi) + I_pin phi''
    alpha = -np.sin(results.t)
    torque = 1.0 * 9.81 * 0.5 * np.cos(phi) + (0.1 + 1.0 * 0.25) * alpha
    # the torque from accelerations one linear solve past q: a few digits fewer than the angle
    assert np.max(np.abs(results["drive.T_j"] - torque)) < 1e-6 * np.max(np.abs(torque))


def test_without_the_floor_the_python_loop_cannot_converge(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(solve, "RULE", newton.NewtonRule(floor_ulps=0.0))
    results = api.solve(loads(FAR, "far.toml"), backend="reference")
    assert isinstance(results.error, AnalysisError)
