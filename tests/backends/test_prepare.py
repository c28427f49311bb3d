"""One place builds solvers (`symid.backends.prepare`): every backend declares
what it can do (`Capabilities`), prepare refuses what a backend lacks with the
command line's one line, the friction model and a variant's values reach the
solver, and no second copy of the build sequence comes back."""

from __future__ import annotations

import dataclasses
import platform
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from symid import api, backends
from symid.backends import Capabilities, Needs
from symid.backends.prepare import needs_of, prepare
from symid.cli.entry import main
from symid.errors import InputError
from symid.io.reader import loads
from symid.model.params import parameter_values
from symid.symbolic.assemble import assemble

PACKAGE = Path(__file__).resolve().parents[2] / "symid"
G, M, MU, VISC, VS, NORMAL_ARM = 9.81, 2.0, 0.3, 0.7, 1e-2, 0.1

# A block pushed along a rail with Coulomb and viscous friction; a side force
# P at height h loads the rail's normal through the arm (tests/test_friction.py's).
RAIL = f"""
[mechanism]
name = "rail"
gravity = [0.0, -{G}]
[parameters]
A = 0.2
w = 3.0
P = 4.0
h = 0.05
mu = {MU}
[analysis]
t0 = 0.0
t1 = 2.0
steps = 21
[[body]]
name = "block"
mass = {M}
inertia = 0.01
q0 = [0.0, 0.0, 0.0]
[[constraint]]
name = "rail"
type = "translational"
i = "ground"
j = "block"
si = [0.0, 0.0]
vi = [2.0, 0.0]
sj = [0.0, 0.0]
friction = {{ mu = "mu", viscous = {VISC}, arm = {NORMAL_ARM}, v_smooth = {VS} }}
[[constraint]]
name = "push"
type = "coordinate_driver"
body = "block"
coordinate = "x"
f = "A*sin(w*t)"
[[force]]
name = "side"
type = "point_force"
body = "block"
s = [0.0, "h"]
F = ["P", "0"]
"""


def rail_friction(t: np.ndarray, mu: float) -> np.ndarray:
    """The rail's friction force by hand: -(mu N tanh(v / vs) + c v), N = m g + h P / arm."""
    v = 0.2 * 3.0 * np.cos(3.0 * t)
    normal = M * G + 0.05 * 4.0 / NORMAL_ARM
    return -(mu * normal * np.tanh(v / VS) + VISC * v)


def test_every_backend_declares_frozen_capabilities_that_its_evaluator_shares() -> None:
    for name in backends.names():
        backend = backends.get(name)
        assert "capabilities" in vars(type(backend)), f"{name}: declared on the class, not inherited"
        caps = backend.capabilities
        assert isinstance(caps, Capabilities)
        with pytest.raises(dataclasses.FrozenInstanceError):
            caps.own_loop = not caps.own_loop  # type: ignore[misc]
        assert backends.capabilities(name) is caps


@pytest.mark.parametrize("name", ["reference", "numpy", "casadi", "c"])
def test_declared_capabilities_match_what_the_backend_implements(name: str) -> None:
    """A declaration is read instead of probing: it must say what the classes do."""
    import importlib

    module, cls = backends._REGISTRY[name]
    backend_class = getattr(importlib.import_module(module), cls)
    caps = backend_class.capabilities
    evaluator_class = {"reference": "ReferenceEvaluator", "numpy": "NumpyEvaluator", "casadi": "CasadiEvaluator",
                       "c": "CEvaluator"}[name]
    ev = getattr(importlib.import_module(module), evaluator_class)
    assert ev.capabilities is caps
    assert caps.own_loop == hasattr(ev, "rows")
    assert caps.blocks == hasattr(ev, "blocks")
    assert caps.with_params == hasattr(ev, "with_params")
    assert caps.sensitivities == hasattr(ev, "sensitivity_row")
    assert caps.loads == hasattr(backend_class, "load")
    assert not caps.blocks or caps.own_loop
    assert not caps.batch_friction or caps.batch is not None


def test_prepare_refuses_what_a_backend_lacks_with_the_command_lines_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = str(api.example("slider_crank"))
    status = main(["solve", path, "--backend", "c", "--cond", "-o", str(tmp_path / "out.csv")])
    err = capsys.readouterr().err.splitlines()
    assert status == 2 and len(err) == 1
    with pytest.raises(InputError) as refused:
        prepare(api.load_mechanism(path, cond_column=True), "c")
    assert err[0] == f"symid: {refused.value}"
    assert "the c backend does not support the cond column" in err[0]
    assert not list(tmp_path.iterdir())


def test_prepare_refuses_a_batch_entry_a_backend_lacks() -> None:
    mech = api.load_mechanism(api.example("slider_crank"))
    for name in backends.names():
        if backends.capabilities(name).batch is None:
            with pytest.raises(InputError, match=f"the {name} backend has no batch entry; use --backend numpy or c"):
                prepare(mech, name, dataclasses.replace(needs_of(mech), batch=True))


# slow: two c builds of the slider-crank (a solve's and a study's); the c backend's solves and studies stay in
# the quick tier
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
def test_the_c_backend_compiles_what_it_calls_set_points_never_lanes_for_a_batch() -> None:
    """A solve's solver has no set-point entry nor SIMD lanes (nothing calls
    them: half the compile), a study's (Needs.batch) has the lanes its sweep
    runs; the slider-crank has a driver, so its export has a set-point entry."""
    import ctypes

    mech = api.load_mechanism(api.example("slider_crank"))
    solve = prepare(mech, "c").evaluator
    batch = prepare(mech, "c", dataclasses.replace(needs_of(mech), batch=True)).evaluator
    assert solve.artifact != batch.artifact  # two cache entries
    for ev, lanes in ((solve, False), (batch, True)):
        source = next(Path(ev.artifact).glob("*_solver.c")).read_text()
        assert "slider_crank_setpoint(" not in source and not hasattr(ev.lib, "slider_crank_setpoint")
        width = ev.lib["slider_crank_sweep_lanes"]  # variants side by side: 1 without lanes, 2 or 4 with
        width.argtypes, width.restype = [ctypes.c_void_p], ctypes.c_long
        assert width(None) == 1 if not lanes else width(None) > 1 or platform.machine() not in ("x86_64", "AMD64")
        assert ("slider_crank_w2_" in source) == lanes  # the SSE2 lanes' code, compiled on any x86-64 or not
    assert "slider_crank_setpoint(" in (PACKAGE.parent / "generated/slider_crank/c/slider_crank_solver.c").read_text()


def test_an_unknown_backend_is_refused_naming_the_valid_ones() -> None:
    with pytest.raises(InputError, match="unknown backend 'fortran' \\(valid: numpy, reference, c, casadi\\)"):
        prepare(api.load_mechanism(api.example("slider_crank")), "fortran")


@pytest.mark.parametrize("backend", ["reference", "numpy"])
def test_the_solver_carries_the_friction_model_and_a_variant_its_own(backend: str) -> None:
    """Friction against the closed form, at the file's mu and at another
    variant's through `Solver.with_values` (which must move the model too)."""
    mech = loads(RAIL, "rail.toml")
    solver = prepare(mech, backend)
    assert solver.friction is not None and solver.evaluator.friction is solver.friction
    a = mech.analysis
    t = np.linspace(a.t0, a.t1, a.steps)
    res = api.Study(mech, solver.layout, solver.evaluator, solver.values, solver=solver).solve()
    assert res.error is None
    # 1e-10: Newton's tolerance and the friction iteration's, on forces of order 10 N
    np.testing.assert_allclose(res["rail.friction"], rail_friction(t, MU), rtol=1e-10, atol=1e-10)
    values = dict(solver.values)
    values[next(s for s in values if s.name == "mu")] = 0.05
    other = solver.with_values(values)
    res = api.Study(mech, other.layout, other.evaluator, other.values, solver=other).solve()
    np.testing.assert_allclose(res["rail.friction"], rail_friction(t, 0.05), rtol=1e-10, atol=1e-10)


def test_facts_are_computed_once_on_the_model() -> None:
    """q0 at the parameter values (by hand from the file), computed once and
    read-only; the reactions a run solves follow [analysis]."""
    mech = api.load_mechanism(api.example("slider_crank"))
    layout = assemble(mech)
    assert layout.values == parameter_values(mech.parameters)
    assert layout.q0 is layout.q0 and not layout.q0.flags.writeable
    assert layout.q0.shape == (layout.ng,) == (3 * layout.nb,)
    np.testing.assert_array_equal(layout.q0, [0.05, 0, 0, 0.25, 0, 0, 0.4, 0, 0])  # the file's q0 (L_crank/2...)
    assert mech.solved_reactions == mech.chosen_reactions == tuple(c.name for c in mech.constraints)
    kinematics = api.load_mechanism(api.example("slider_crank"), kind="kinematics")
    assert kinematics.solved_reactions == () and needs_of(kinematics) == Needs(velocity=True, reactions=())
    statics = api.load_mechanism(api.example("slider_crank"), kind="statics", reactions=["motor"])
    assert statics.solved_reactions == ("motor",) and not needs_of(statics).velocity


# Steps of the build sequence: only symid/backends/prepare.py runs them (and
# the registry module, which defines the checks); a second copy elsewhere is
# what issue #27 removed.
SEQUENCE = {
    "a backend's evaluator built": re.compile(r"\.evaluator\(\s*layout|chosen\.evaluator\("),
    "a friction model built": re.compile(r"\bFrictionModel\("),
    "the backend checks": re.compile(r"\b(require_support|check_redundant)\("),
    "a friction model attached": re.compile(r"\.friction\s*=\s*FrictionModel|friction\.attach\("),
    "a backend probed": re.compile(r"(getattr|hasattr)\([^)]*[\"'](rows|blocks|with_params|lacks|solves_friction|"
                                   r"artifact|load|sensitivity_header)[\"']"),
    "a backend named in a branch": re.compile(r"backend\s*(==|!=|in)\s*[\"'(]"),
}
ALLOWED = {"backends/prepare.py", "backends/__init__.py", "numeric/friction.py"}


def test_no_second_copy_of_the_build_sequence() -> None:
    assert (PACKAGE / "backends" / "prepare.py").is_file()  # the scan below reads the package, not nothing
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        where = path.relative_to(PACKAGE).as_posix()
        if where in ALLOWED or where.startswith("cli/"):
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            found += [f"{where}:{number}: {what}" for what, pattern in SEQUENCE.items() if pattern.search(line)]
    assert not found, "build steps outside symid/backends/prepare.py:\n" + "\n".join(found)
