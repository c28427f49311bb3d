"""At and near a singular position every backend makes the same conditioning
checks (issue 26, point 1): `--backend c` solved a scissor lift whose arms
end exactly flat with exit 0, a peak force of 1e11-1e12 N and no warning,
where numpy warned "ill-conditioned". The C loop now screens each instant's
pivots in the Python loop's scales and hands a suspicious instant to the
Python loop, which estimates the condition number and warns (or stops) for
every backend alike.

Two mechanisms, both driven onto a singular position at t1 by a law with a
parameter `e`, the distance left from it (radians of the arm or crank):
a scissor lift driven by its sliding foot (flat arms: the foot's position no
longer fixes their angle, and lifting the platform needs an infinite force)
and a slider-crank driven by its piston against a torque on the crank (dead
centre). Truth is independent of the code: the condition number grows like
1 / e, so e = 1e-7 is past cond_warn = 1e6 and e = 0.05 is far below it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from symid import api, cli
from scissor import scissor_lift
from tiers import first_quick

BACKENDS = ("reference", "numpy", "casadi", "c")

SCISSOR = scissor_lift("scissor", """
L = 1.0
a0 = 0.6
c0 = 0.6                       # the arms' angle in q0
e = 0.0
m_arm = 5.0
m_top = 50.0
""", 101, "c0", "pi - c0", "{drive}", "m_arm", "m_top")
# the foot's position for arms at a0 (1 - t) + e: flat at t1 when e = 0
SMOOTH = "L*cos(a0*(1 - t) + e)"
# the foot pushed at constant speed to where the arms lie flat (the issue's
# case: its angle goes as sqrt(1 - t), so Newton stops short of flat by
# rounding, where the condition number is 1e8, not at the exact singularity)
LINEAR = "L*cos(a0) + L*(1 - cos(a0))*t"
# arms that start e from flat (t0 is solved before the scales of the checks are known)
RISING = "L*cos(a0*t + e)"

CRANK = """
[mechanism]
name = "piston_driven"

[parameters]
r = 0.1
l = 0.3
a0 = 1.0
e = 0.0

[analysis]
t1 = 1.0
steps = 101

[[body]]
name = "crank"
mass = 0.5
inertia = 0.0005
q0 = ["r/2*cos(a0)", "r/2*sin(a0)", "a0"]

[[body]]
name = "rod"
mass = 1.0
inertia = 0.0075
q0 = ["r*cos(a0) + (sqrt(l^2 - (r*sin(a0))^2))/2", "r*sin(a0)/2", "-asin(r*sin(a0)/l)"]

[[body]]
name = "piston"
mass = 0.8
inertia = 0.001
q0 = ["r*cos(a0) + sqrt(l^2 - (r*sin(a0))^2)", 0.0, 0.0]

[[constraint]]
name = "main"
type = "revolute"
i = "ground"
j = "crank"
si = [0.0, 0.0]
sj = ["-r/2", 0.0]

[[constraint]]
name = "crank_pin"
type = "revolute"
i = "crank"
j = "rod"
si = ["r/2", 0.0]
sj = ["-l/2", 0.0]

[[constraint]]
name = "wrist"
type = "revolute"
i = "rod"
j = "piston"
si = ["l/2", 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "guide"
type = "translational"
i = "ground"
j = "piston"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "stroke"
type = "translational_driver"
i = "ground"
j = "piston"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
f = "r*cos(a0*(1 - t) + e) + sqrt(l^2 - (r*sin(a0*(1 - t) + e))^2)"

[[force]]
name = "brake"
type = "torque"
body = "crank"
T = -20.0
"""

# The numbers of a warning at a singular position are rounding: the
# condition estimate there is (1e8 or 1e14) times a rounding error, and
# differs between backends in its leading digits. The text around them, the
# instants and their times, must not.
_ROUNDING = [(re.compile(r"worst [^ ]+ at"), "worst X at"), (re.compile(r"up to \d+ of"), "up to N of"),
             (re.compile(r"condition estimate [^)]+\)"), "condition estimate X)")]


def _text(line: str) -> str:
    for pattern, mask in _ROUNDING:
        line = pattern.sub(mask, line)
    return line


def _write(tmp_path: Path, text: str, name: str) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _solve_cli(path: Path, backend: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], *extra: str,
               ) -> tuple[int, list[str], np.ndarray]:
    out = tmp_path / f"{backend}.csv"
    status = cli.main(["solve", str(path), "--backend", backend, "-o", str(out), *extra])
    err = capsys.readouterr().err.replace(str(out), "OUT").strip().splitlines()
    data = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2) if out.exists() else np.zeros((0, 0))
    return status, [_text(line) for line in err], data


CASES = {
    # (file, extra arguments, exit status, what the one stderr line says)
    "scissor_flat_statics": (SCISSOR.format(drive=LINEAR), ("--kind", "statics"), 0, "ill-conditioned"),
    "scissor_near_flat": (SCISSOR.format(drive=SMOOTH), ("--set", "e=1e-7"), 0, "ill-conditioned"),
    "scissor_flat": (SCISSOR.format(drive=SMOOTH), (), 3, "Phi_q is singular"),
    "scissor_starts_near_flat": (SCISSOR.format(drive=RISING), ("--set", "e=1e-7", "--set", "c0=1e-7"), 0,
                                 "ill-conditioned"),
    "crank_near_dead_centre": (CRANK, ("--set", "e=1e-6"), 0, "ill-conditioned"),
    "crank_dead_centre_statics": (CRANK, ("--kind", "statics"), 0, "ill-conditioned"),
}


@pytest.mark.parametrize("case", first_quick(["crank_near_dead_centre", "scissor_flat"]
                                               + sorted(set(CASES) - {"crank_near_dead_centre", "scissor_flat"})))
# the quick tier: a warning (exit 0; the singular stop, exit 3, is tests/backends/test_singular_names_constraints.py's);
# the others are the same screen at other positions
def test_every_backend_warns_alike_at_a_singular_position(case: str, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    text, extra, status, said = CASES[case]
    path = _write(tmp_path, text, case)
    runs = {b: _solve_cli(path, b, tmp_path, capsys, *extra) for b in BACKENDS}
    reference = runs["reference"]
    assert reference[0] == status, reference[1]
    assert any(said in line for line in reference[1]), reference[1]
    for backend, (got, lines, data) in runs.items():
        assert (got, lines) == reference[:2], f"{backend}: exit {got}, {lines}; the reference {reference[:2]}"
        assert len(data) == len(reference[2]), f"{backend}: {len(data)} instants, the reference {len(reference[2])}"


NEAR = {  # well away from the singular position: cond in the tens to hundreds
    "scissor": (SCISSOR.format(drive=SMOOTH), 0.05),
    "crank": (CRANK, 0.05),
}


@pytest.mark.parametrize("name", sorted(NEAR))
def test_near_a_singular_position_nothing_warns_and_backends_agree(name: str, tmp_path: Path) -> None:
    text, e = NEAR[name]
    path = _write(tmp_path, text, name)
    tables = {}
    for backend in BACKENDS:
        results = api.prepare(path, backend=backend, set_values={"e": repr(e)}).solve()
        assert results.error is None and results.warnings == [], (backend, results.error, results.warnings)
        tables[backend] = results
    columns = tables["reference"].columns
    forces = [k for k, c in enumerate(columns) if c.split(".")[-1] in ("Fx_i", "Fy_i", "T_i", "Fx_j", "Fy_j", "T_j")]
    for backend, results in tables.items():
        assert results.columns == columns
        ref, got = tables["reference"].data[:, forces], results.data[:, forces]
        # forces keep 16 - 2 log10(cond) digits (docs/analysis-options.md): with cond below a
        # few hundred that is 1e-12 of the run's largest force or better
        peak = np.abs(ref).max()
        # (the bound the comment above derives)
        assert np.abs(got - ref).max() <= 1e-12 * peak, (backend, np.abs(got - ref).max() / peak)


@pytest.mark.slow  # a c sweep and a solve of a screened variant; the screen's warning stays in the quick tier
def test_the_c_sweep_hands_a_screened_variant_to_the_solve(tmp_path: Path) -> None:
    """A sweep's variant whose C loop trips the screen (in SIMD lanes or one
    by one) goes back to the normal path, as the NumPy sweep's does: its
    figures are those of its own `symid solve` on c, which warns."""
    from symid.study import batch_c
    from symid.study.engine import solve_figures
    from symid.study.variants import base_matrix, study_mechanism

    path = _write(tmp_path, SCISSOR.format(drive=SMOOTH), "scissor")
    mech = api.load_mechanism(path)
    values = [1e-7, 0.05, 0.1, 0.2]  # a group of lanes where the processor has them
    base = np.array([[v] for v in values])
    study = study_mechanism(mech)
    batch = batch_c.run(study, base_matrix(study, ("e",), base), 1)
    assert list(batch.status) == [6, 0, 0, 0], batch.status  # the C code's ILL_CONDITIONED
    figures = solve_figures(mech, ("e",), base, "c", 1)
    assert list(figures.status) == [0] * 4
    for k, v in enumerate(values):
        own = api.prepare(path, backend="c", set_values={"e": repr(v)}).solve()
        assert own.error is None and bool(own.warnings) == (k == 0), own.warnings
        peak = np.abs(own["drive.lambda"]).max()
        got = figures.values[k, figures.names.index("drive.effort_peak")]
        # the sweep's figure is the peak of the same compiled solve: equal to rounding
        assert abs(got - peak) <= 1e-12 * peak, (v, got, peak)


@pytest.mark.slow  # a sweep whose variants the screen reads at t0; the screen's warning stays in the quick tier
def test_a_sweep_screens_its_variants_t0(tmp_path: Path) -> None:
    """t0 is solved before the scales of the checks are known: the sweep
    screens it once they are (`_screen_at`), as `symid solve` on c does."""
    from symid.study import batch_c
    from symid.study.engine import solve_figures
    from symid.study.variants import base_matrix, study_mechanism

    path = _write(tmp_path, SCISSOR.format(drive=RISING), "rising")
    mech = api.load_mechanism(path, {"c0": "1e-7"})
    study = study_mechanism(mech)
    base = np.array([[1e-7]])
    batch = batch_c.run(study, base_matrix(study, ("e",), base), 1)
    assert list(batch.status) == [6] and list(batch.solved) == [1], (batch.status, batch.solved)
    own = api.prepare(path, backend="c", set_values={"c0": "1e-7", "e": "1e-7"}).solve()
    assert own.error is None and own.warnings and "t in [0, 0]" in own.warnings[0], own.warnings
    figures = solve_figures(mech, ("e",), base, "c", 1)
    peak = np.abs(own["drive.lambda"]).max()
    # the sweep's figure is the peak of the same compiled solve: equal to rounding
    assert abs(figures.values[0, figures.names.index("drive.effort_peak")] - peak) <= 1e-12 * peak
