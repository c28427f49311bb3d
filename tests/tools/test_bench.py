"""The benchmark never rots: `symid bench`, the ladder's closed form and a
smoke run of `benchmarks/run.py` (tiny sizes). No timing assertions."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import ladder  # noqa: E402


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_symid_bench_json_has_the_documented_keys(backend: str, capsys: pytest.CaptureFixture[str]) -> None:
    status = main(["bench", str(api.example("slider_crank")), "--backend", backend, "--instants", "12", "--json"])
    assert status == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("us_per_instant", "setup_s", "derive_s", "generate_s", "compile_s", "max_residual", "instants"):
        assert key in result
    assert result["instants"] == 12
    assert result["us_per_instant"] > 0 and result["setup_s"] > 0
    # the constraint residual after Newton to tol 1e-12, for lengths of order 1 (1e-10 with room)
    assert result["max_residual"] <= 1e-10
    assert result["error"] is None


@pytest.mark.parametrize("n", [1, 2])
def test_ladder_motor_torque_matches_its_closed_form(n: int, tmp_path: Path) -> None:
    path = ladder.write(n, tmp_path, steps=201)
    results = api.solve(path, "reference")
    lad = ladder.Ladder(n)
    assert results.error is None
    assert len(results.columns) > 1 and results.data.shape[0] == 201
    exact = lad.torque(results.t)
    # the ladder's closed-form torque against a tol 1e-12 solve: rounding grows with the chain, 1e-10 leaves room
    assert np.max(np.abs(results["motor.T_j"] - exact)) <= 1e-10 * np.max(np.abs(exact))
    assert api.prepare(path).layout.ng == lad.ng == 6 * n + 3


def test_ladder_exact_configuration_is_assembled(tmp_path: Path) -> None:
    lad = ladder.Ladder(3)
    study = api.prepare(ladder.write(3, tmp_path, steps=11), "reference")
    for t in (0.0, 0.3, 0.77):
        # the ladder's exact q satisfies Phi: rounding of coordinates of order 1
        assert np.max(np.abs(study.evaluator.phi(lad.q_exact(t), t))) <= 1e-14


@pytest.mark.slow  # the benchmark harness itself, every approach at tiny sizes
def test_benchmark_smoke_run_writes_every_output(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "benchmarks.run", "--smoke", "--out", str(tmp_path)],
                          cwd=ROOT, capture_output=True, text=True)  # no deadline: under load it takes minutes
    assert done.returncode == 0, done.stderr[-2000:]
    for name in ("bench.json", "bench.md", "time_vs_ng.png", "time_vs_error.png", "tolerance_sweep.png"):
        assert (tmp_path / name).is_file(), name
    result = json.loads((tmp_path / "bench.json").read_text())
    approaches = {c["approach"] for c in result["cells"]}
    assert {"numpy-hand", "sympy-lambdify", "casadi-python", "casadi-c", "symid-c", "symid-numpy",
            "symid-reference", "symid-casadi"} <= approaches
    # the ratio targets are read from the paired worker, the cached-solve and
    # streaming targets from the processes: both must have run
    assert result["paired"] and all(v["status"] == "ok" and v["ratio"] > 0 and v["rounds"] >= 3
                                    for v in result["paired"].values()), result["paired"]
    processes = result["processes"]
    assert all(r["status"] == 0 and r["wall_s"] > 0 for r in processes["solve_1001"].values())
    assert set(processes["solve_1001"]) == {"numpy", "c"}
    assert processes["stream"]["status"] == 0 and processes["stream"]["peak_rss_mb"] > 0
    for cell in result["cells"]:
        assert cell["status"] == "ok", cell
        # each cell's error against the closed form: the bound of the ladder tests
        assert cell["error_rel"] <= 1e-10, cell
        assert cell["us_per_instant"] > 0 and cell["peak_rss_mb"] > 0
    assert all(s["status"] == "ok" for s in result["sweeps"].values())
    assert "| approach |" in (tmp_path / "bench.md").read_text()
    # the design study beside CasADi's C loop and CasADi's map from Python (issue 14)
    study = result["study"]
    assert study["status"] == "ok", study
    assert study["grid"]["threads_2"]["failed"] == 0 and study["grid"]["threads_2"]["instants_per_s"] > 0
    assert study["casadi_map"]["us_per_instant"] > 0 and study["casadi_c"]["us_per_instant_1_thread"] > 0
    assert 'Function.map(K, "thread", 2)' in (tmp_path / "bench.md").read_text()


@pytest.mark.parametrize("backend", ["c", "numpy", "reference", "casadi"])
def test_a_ladder_far_from_the_origin_keeps_its_torque_to_1e_13(backend: str, tmp_path: Path) -> None:
    # At x ~ 16384 m a coordinate's ulp is 3.6e-12: a residual summed left
    # to right rounds there, and eight bays in series turn that into torque
    # errors of ~1e-12 of the peak. Grouping the coordinate differences first
    # (symid.symbolic.rounding) keeps the residual exact. Pivots and lengths are exact
    # binary numbers, so the file's mechanism is exactly a parallelogram ladder.
    dims = {"x0": 16384.0, "a": 0.5, "b": 0.5}
    lad = ladder.Ladder(8, **dims)
    results = api.solve(ladder.write(8, tmp_path, steps=101, **dims), backend)
    assert results.error is None
    exact = lad.torque(results.t)
    # far from the origin the solver keeps relative precision: 1e-13 of the peak, the point of this test
    assert np.max(np.abs(results["motor.T_j"] - exact)) <= 1e-13 * np.max(np.abs(exact))
    assert np.max(np.abs(results.data[:, 1:1 + lad.ng] - np.array([lad.q_exact(t) for t in results.t]))) <= 1e-11
