"""Design studies of a mechanism with joint friction (#14 with #16): every
variant's figures equal those of its own `symid solve --set` table (computed
here from the table's columns), `Study.solve_many` gives each variant its own
run, and the friction parameters reach every path (mu = 0 and mu = 0.1 differ)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main
from tiers import first_quick

EXAMPLE = str(api.example("slider_crank_friction"))
STEPS = "9"
JOINTS = ("main_bearing", "crank_pin", "wrist_pin", "cylinder_guide", "motor")
FIGURES = ["motor.effort_peak", "motor.effort_t_peak", "motor.effort_rms", "motor.power_peak",
           *(f"{j}.force_peak" for j in JOINTS)]
OMEGA = 2 * math.pi * 5  # the example's crank speed, rad/s (n = 5 rev/s)


def read_table(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float).reshape(len(rows) - 1, len(rows[0]))


def own_figures(tmp_path: Path, capsys, backend: str, values: dict[str, str]) -> dict[str, float]:
    """The figures of the variant's own `symid solve --set` table, from its columns:
    the motor torque `motor.T_j` (the whole action on the crank), its power
    T_j * omega, the largest |(Fx, Fy)| of each joint (reaction plus friction)."""
    out = tmp_path / f"solve_{len(list(tmp_path.iterdir()))}.csv"
    sets = [a for name, value in values.items() for a in ("--set", f"{name}={value}")]
    status = main(["solve", EXAMPLE, "--steps", STEPS, "--backend", backend, "-o", str(out), *sets])
    capsys.readouterr()
    assert status == 0
    header, data = read_table(out)
    col = {c: data[:, k] for k, c in enumerate(header)}
    assert "main_bearing.friction" in col  # the variant's own run solved friction
    t, torque = col["t"], col["motor.T_j"]
    k = int(np.argmax(np.abs(torque)))
    rms = math.sqrt(float(np.sum((torque[1:] ** 2 + torque[:-1] ** 2) * np.diff(t))) / 2 / (t[-1] - t[0]))
    figures = {"motor.effort_peak": abs(torque[k]), "motor.effort_t_peak": t[k], "motor.effort_rms": rms,
               "motor.power_peak": float(np.max(np.abs(torque * OMEGA)))}
    for joint in JOINTS:
        roles = [c.rpartition("_")[2] for c in header if c.startswith(f"{joint}.Fx_")]
        figures[f"{joint}.force_peak"] = max(float(np.max(np.hypot(col[f"{joint}.Fx_{r}"], col[f"{joint}.Fy_{r}"])))
                                             for r in roles)
    return figures


@pytest.mark.parametrize("backend", ["c", "numpy", "casadi"])
def test_sweep_figures_with_friction_equal_each_variants_own_solve(tmp_path, capsys, backend):
    out = tmp_path / "sweep.csv"
    status = main(["sweep", EXAMPLE, "--steps", STEPS, "--grid", "mu_pin=0:0.1:2", "--grid", "L_rod=0.28:0.32:2",
                   "--backend", backend, "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 0, err
    with out.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["mu_pin"], r["L_rod"]) for r in rows] == [("0", "0.28000000000000003"), ("0", "0.32000000000000001"),
                                                         ("0.10000000000000001", "0.28000000000000003"),
                                                         ("0.10000000000000001", "0.32000000000000001")]
    for row in rows:
        assert row["status"] == "ok", row
        expected = own_figures(tmp_path, capsys, backend, {"mu_pin": row["mu_pin"], "L_rod": row["L_rod"]})
        for name in FIGURES:
            # the figure from the sweep and from its own solve: the same arithmetic up to summation order (1e-12 relative; atol: zero figures)
            np.testing.assert_allclose(float(row[name]), expected[name], rtol=1e-12, atol=1e-300, err_msg=name)
    # the friction coefficient reaches the sweep: mu_pin = 0.1 takes more than mu_pin = 0
    peaks = [float(r["main_bearing.force_peak"]) for r in rows]
    rms = [float(r["motor.effort_rms"]) for r in rows]
    assert abs(rms[2] - rms[0]) > 1e-3 * rms[0] and abs(rms[3] - rms[1]) > 1e-3 * rms[1]
    assert peaks[2] != peaks[0]


# every friction key through a parameter: coefficients, radius, viscous, arm
NAMES = ("mu_pin", "r_main", "c_main", "mu_guide", "a_slider")
BASE = np.array([[0.0, 0.012, 0.0, 0.0, 0.06], [0.1, 0.02, 0.01, 0.2, 0.04], [0.05, 0.01, 0.002, 0.1, 0.08]])


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_solve_many_with_friction_parameters_gives_each_variants_own_run(backend):
    study = api.prepare(api.example("slider_crank_friction"), backend, steps=int(STEPS))
    runs = [r for chunk in study.solve_many(BASE, NAMES, chunk=2) for r in chunk]
    assert len(runs) == len(BASE)
    for row, results in zip(BASE, runs):
        own = api.prepare(api.example("slider_crank_friction"), backend, steps=int(STEPS),
                          set_values={n: repr(float(v)) for n, v in zip(NAMES, row)}).solve()
        assert results.error is None and own.error is None
        assert results.columns == own.columns
        # a variant and its own solve: the same arithmetic, rounding
        np.testing.assert_allclose(results.data, own.data, rtol=1e-12, atol=1e-12 * np.abs(own.data).max())
    # without friction (every coefficient 0) no joint loses power; with it they do
    loss = [float(np.abs(r["main_bearing.friction_power"]).max()) for r in runs]
    assert loss[0] == 0.0 and loss[1] > 0.0 and loss[2] > 0.0
    # the friction changes the torque by far more than 1e-6: they differ
    assert not np.allclose(runs[0]["motor.T_j"], runs[1]["motor.T_j"], rtol=1e-6)


@pytest.mark.parametrize("unrolled", first_quick([4, 0], ids=["written_out", "dense"]))
def test_c_friction_newton_system_solved_either_way_matches_the_reference(monkeypatch, tmp_path, unrolled):
    """The generated solve of the NF x NF Newton system, written out (NF <= 4)
    or by the dense solver (past it), gives the reference's run to 1e-10, and
    is the exact Newton's: at most 3 iterations on the example (issue #16's
    target; a wrong solve still converges, but slower), every instant in the
    compiled loop."""
    from symid.codegen import friction as codegen_friction
    from symid.numeric import solve

    monkeypatch.setenv("SYMID_CACHE", str(tmp_path))  # the cache key does not see these: a build of its own
    monkeypatch.setattr(codegen_friction, "UNROLLED", unrolled)
    monkeypatch.setattr(codegen_friction, "MAX_ITERATIONS", 3)
    handed = []
    original = solve.Stepper.instant
    monkeypatch.setattr(solve.Stepper, "instant", lambda self, n, *a: handed.append(n) or original(self, n, *a))
    c = api.solve(api.example("slider_crank_friction"), backend="c", steps=21)
    assert handed == []  # no instant failed in C and went to the Python loop
    ref = api.solve(api.example("slider_crank_friction"), backend="reference", steps=21)
    source = next(tmp_path.rglob("slider_crank_friction_solver.c")).read_text()
    assert ("u33 = a[15]" in source) == (unrolled == 4)  # the written-out elimination, or none
    assert c.columns == ref.columns
    scale = np.abs(ref.data).max(axis=0) + 1e-300
    # the C and the reference solve the same equations to tol 1e-12; smoothed friction near reversal costs digits (1e-10 per column)
    assert np.max(np.abs(c.data - ref.data) / scale) <= 1e-10
