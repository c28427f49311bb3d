"""No number without a guarantee, on every backend.

An expression that leaves its domain at run time (a pole, log(0), sqrt of a
negative, exp overflow, asin past 1) or a value beyond the doubles (a mass of
1e308) stops the run with exit 3 at that instant, naming the element, and
keeps the rows before, equal to the reference backend's. A four-bar driven
exactly onto its toggle stops there on every backend; one driven near it
passes, the same on every backend.

Each family is one mechanism whose cases are parameter values (`--set`), so
each backend builds one solver for all of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import stress
from compare import assert_agree as _agree
from symid import api
from symid.cli import main
from tiers import diagonal

BACKENDS = ("numpy", "c", "casadi", "reference")

# The bundled slider-crank at 1 rev/s, 17 instants on [0, 0.5] (h = 1/32:
# t = 0.25 is the grid's 9th instant exactly), with every domain edge in one
# file, each far away (finite) unless a case moves it to t = 0.25.
DOMAINS = {
    "pole": ("tp", "force brake"),       # brake torque 1/(t - tp): inf at tp
    "log": ("tl", "force brake"),        # log(tl - t): -inf at tl
    "exp": ("k", "force brake"),         # exp(k t): past 709.78 it overflows
    "sqrt": ("ts", "constraint motor"),  # the driver's sqrt(ts - t): f' is inf at ts, NaN after
    "asin": ("ta", "constraint motor"),  # asin(t / ta): f' is inf at ta, NaN past it
}
VALUE = {"tp": "0.25", "tl": "0.25", "k": "2840", "ts": "0.25", "ta": "0.25"}
STOP = 0.25
ROWS_BEFORE = 8  # t = 0 .. 7/32


def _domains_text() -> str:
    text = api.example("slider_crank").read_text(encoding="utf-8")
    text = text.replace("n = 5 ", "n = 1 ").replace("t1 = 0.2 ", "t1 = 0.5 ").replace("steps = 201", "steps = 17")
    text = text.replace("[parameters]\n", "[parameters]\ntp = 100.0\ntl = 100.0\nk = 1.0\nts = 100.0\nta = 100.0\n")
    text = text.replace('f = "omega*t"', 'f = "omega*t + sqrt(ts - t) - sqrt(ts) + asin(t/ta)"')  # 0 at t0
    return text + ('\n[[force]]\nname = "brake"\ntype = "torque"\nbody = "crank"\n'
                   'T = "1/(t - tp) + log(tl - t) + exp(k*t)"\n')


# The stress four-bar (crank 1, coupler 1.5, rocker 1, ground 2) driven to
# `delta` rad before its toggle at t = 0.5 and back: th - delta - (t - 0.5)^2.
def _toggle_text() -> str:
    text = stress.FOUR_BAR.replace("th = 1.0", f"th = {stress.TOGGLE!r}\ndelta = 0.0")
    text = text.replace('f = "th + omega*t"', 'f = "th - delta - omega*(t - 0.5)^2"')
    text = text.replace("omega = 10.0", "omega = 1.0")
    return text.replace("steps = 1\n", "t1 = 1.0\nsteps = 11\n").replace(', "cond"]', "]")


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("nonfinite")
    out = {}
    for name, text in (("domains", _domains_text()), ("toggle", _toggle_text())):
        out[name] = folder / f"{name}.toml"
        out[name].write_text(text, encoding="utf-8")
    return out


def _solve(capsys, path: Path, out: Path, backend: str, *extra: str) -> tuple[int, list[str]]:
    """(status, stderr lines) of `symid solve` with NAME=VALUE settings and
    --flags, after checking that no traceback escaped."""
    args = ["solve", str(path), "-o", str(out), "--backend", backend]
    for s in extra:
        args += [s] if s.startswith("--") else ["--set", s]
    status = main(args)
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Error:" not in err, err
    return status, err.splitlines()


def _rows(path: Path) -> np.ndarray:
    lines = path.read_text().splitlines()
    width = len(lines[0].split(","))
    return np.array([[float(v) for v in line.split(",")] for line in lines[1:]]).reshape(len(lines) - 1, width)


@pytest.fixture(scope="module")
def reference_rows(files, tmp_path_factory) -> dict[str, np.ndarray]:
    """The reference backend's rows before the stop, one run per case."""
    folder = tmp_path_factory.mktemp("reference")
    out = {}
    for case, (param, _) in DOMAINS.items():
        csv = folder / f"{case}.csv"
        assert main(["solve", str(files["domains"]), "-o", str(csv), "--backend", "reference",
                     "--set", f"{param}={VALUE[param]}", "--t1", repr(7 / 32), "--steps", str(ROWS_BEFORE)]) == 0
        out[case] = _rows(csv)
    return out


@pytest.mark.parametrize("case, backend", diagonal(list(DOMAINS), BACKENDS))
def test_a_domain_error_stops_at_its_time_naming_the_element_keeping_the_rows(
        files, reference_rows, tmp_path, capsys, case, backend):
    param, element = DOMAINS[case]
    out = tmp_path / "out.csv"
    status, err = _solve(capsys, files["domains"], out, backend, f"{param}={VALUE[param]}")
    assert status == 3 and len(err) == 1, err
    assert f"t = {STOP}:" in err[0] and "not finite" in err[0] and element in err[0], err[0]
    assert f"the {ROWS_BEFORE} instants before it are in" in err[0], err[0]
    rows = _rows(out)
    assert rows.shape[0] == ROWS_BEFORE and np.isfinite(rows).all() and rows[-1, 0] < STOP
    # exp(k t) spans 270 decades over the rows: a rounding of its argument is 1e-12 of it
    _agree(rows, reference_rows[case], 1e-11 if case == "exp" else 1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kinematics_names_only_constraints_and_ignores_force_poles(files, tmp_path, capsys, backend):
    """Kinematics computes no force: the brake's pole does not stop it, and
    with the driver's sqrt edge too only the driver is named."""
    out = tmp_path / "out.csv"
    status, err = _solve(capsys, files["domains"], out, backend, "tp=0.25", "--kind=kinematics")
    assert status == 0, err
    status, err = _solve(capsys, files["domains"], out, backend, "tp=0.25", "ts=0.25", "--kind=kinematics")
    assert status == 3 and len(err) == 1, err
    assert f"t = {STOP}: qdot, qddot not finite" in err[0] and "constraint motor; the 8 instants" in err[0], err[0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_mass_beyond_the_doubles_stops_at_t0_naming_the_body(files, tmp_path, capsys, backend):
    out = tmp_path / "out.csv"
    status, err = _solve(capsys, files["domains"], out, backend, "m_crank=1e308")
    assert status == 3 and len(err) == 1, err
    assert "t = 0:" in err[0] and "not finite" in err[0] and "body crank" in err[0], err[0]
    assert _rows(out).shape[0] == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_run_onto_the_exact_toggle_stops_there_on_every_backend(files, tmp_path, capsys, backend):
    """At the toggle Phi_q is singular to within rounding: the rates solved
    there are noise (qddot ~ 1e7) and the next step would land on another
    branch or whole turns away. Every backend stops at t = 0.5 with exit 3."""
    out = tmp_path / "out.csv"
    status, err = _solve(capsys, files["toggle"], out, backend)
    assert status == 3, err
    assert "t = 0.5: singular position" in err[-1] and "the 5 instants before it" in err[-1], err[-1]
    rows = _rows(out)
    assert rows.shape[0] == 5 and rows[-1, 0] == pytest.approx(0.4)


@pytest.fixture(scope="module")
def near_toggle_reference(files, tmp_path_factory) -> dict[str, np.ndarray]:
    folder = tmp_path_factory.mktemp("near")
    out = {}
    for delta in ("1e-4", "1e-6"):
        csv = folder / f"{delta}.csv"
        assert main(["solve", str(files["toggle"]), "-o", str(csv), "--backend", "reference",
                     "--set", f"delta={delta}"]) == 0
        out[delta] = _rows(csv)
    return out


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("delta", ["1e-4", "1e-6"])
def test_a_run_near_the_toggle_passes_continuously_and_agrees(files, near_toggle_reference, tmp_path, capsys,
                                                              backend, delta):
    """delta rad before the toggle (cond 1e3 to 1e4): every backend exits 0
    with the reference's rows; the motion is symmetric about t = 0.5 and
    the angles continuous (at 1e-6 a Newton from the Taylor guess lands whole
    turns away, which the jump rule follows back)."""
    out = tmp_path / "out.csv"
    status, err = _solve(capsys, files["toggle"], out, backend, f"delta={delta}")
    assert status == 0, err
    rows = _rows(out)
    expected = near_toggle_reference[delta]
    angles = rows[:, 3:10:3]
    assert np.all(np.abs(np.diff(angles, axis=0)) < 0.2), "no jump of the angles"
    # near the toggle Phi_q is nearly singular and the angles lose digits; 1e-6 rad still tells symmetric from a jump (0.2 above)
    assert np.allclose(angles, angles[::-1], rtol=0, atol=1e-6), "symmetric about the toggle"
    _agree(rows[:, :10], expected[:, :10], 1e-8)
