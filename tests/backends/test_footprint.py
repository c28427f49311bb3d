"""The memory a run will use, estimated from the backend and the analysis and
refused up front against SYMID_MEMORY_LIMIT (`symid.backends.footprint`):
the ladder of four-bars (`benchmarks/ladder.py`) is cheap on the C backend,
whose setup is linear, and dense on the Python loop's."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from benchmarks import ladder
from symid import api, backends
from symid.backends import footprint
from symid.backends.c_backend import LARGE_SOURCE
from symid.cli import main
from symid.numeric.stability import SPARSE_MIN
from symid.symbolic.assemble import assemble

EXAMPLES = Path(api.example("four_bar")).parent


def refusal(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    status = main(args)
    return status, " ".join(capsys.readouterr().err.split())


def test_the_dense_part_is_five_copies_of_phi_q_where_the_python_loop_factors_it() -> None:
    """Against the counts: nc x ng doubles, 5 copies, on the Python loop's backends and never on c."""
    layout = assemble(api.load_mechanism(EXAMPLES / "four_bar.toml"))
    dense = 5 * 8 * layout.nc * layout.ng / 2**20
    for backend in ("numpy", "casadi", "reference"):
        assert footprint.estimate(layout, backend).dense_mb == pytest.approx(dense, rel=1e-15), backend
    assert footprint.estimate(layout, "c").dense_mb == 0 and not footprint.dense_checks(layout, "c")


def test_the_python_loop_of_a_large_mechanism_counts_nothing_dense(tmp_path: Path) -> None:
    """From SPARSE_MIN coordinates on the loop factors Phi_q sparse (tests/numeric/test_sparse_checks.py)."""
    layout = assemble(api.load_mechanism(ladder.write(100, tmp_path, steps=11)))  # ng 603
    assert layout.ng >= SPARSE_MIN
    for backend in backends.names():
        assert footprint.estimate(layout, backend).dense_mb == 0, backend


def test_the_setup_grows_linearly_with_the_coordinates(tmp_path: Path) -> None:
    """Ladders of 16 and 64: the setup part differs by the backend's slope times 6 x 48 coordinates."""
    small, large = (assemble(api.load_mechanism(ladder.write(n, tmp_path / str(n), steps=11))) for n in (16, 64))
    for backend in backends.names():
        kb = backends.capabilities(backend).setup_kb
        grown = footprint.estimate(large, backend).setup_mb - footprint.estimate(small, backend).setup_mb
        assert grown == pytest.approx(kb * 6 * 48 / 1024, rel=1e-12), backend


@pytest.mark.slow  # compiles a 33-body ladder; the estimates' tests stay in the quick tier
def test_a_limit_between_the_estimates_refuses_numpy_and_c_solves_the_ladder(tmp_path: Path, capsys,
                                                                               monkeypatch) -> None:
    """SYMID_MEMORY_LIMIT below numpy's estimate and above c's: numpy refused in one
    line (file, resource, estimate, limit, what c needs) before anything is built;
    c solves, its motor torque the ladder's closed form."""
    n = 16
    path = ladder.write(n, tmp_path / "mech", steps=21)
    layout = assemble(api.load_mechanism(path))
    c, numpy = footprint.estimate(layout, "c").total_mb, footprint.estimate(layout, "numpy").total_mb
    assert c < numpy
    limit = round((c + numpy) / 2)
    monkeypatch.setenv("SYMID_MEMORY_LIMIT", f"{limit}M")
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    status, line = refusal(["solve", str(path), "--backend", "numpy", "-o", str(tmp_path / "n.csv")], capsys)
    assert status == 2, line
    assert (f"{path}: memory: a run of {2 * n + 1} bodies (ng {6 * n + 3}) needs about {numpy:.0f} MiB" in line
            and f"more than the {limit} MiB allowed (SYMID_MEMORY_LIMIT sets it); --backend c needs about "
                f"{c:.0f} MiB" in line), line
    assert not (tmp_path / "n.csv").exists() and not any((tmp_path / "cache").rglob("*"))  # nothing built
    assert main(["solve", str(path), "--backend", "c", "-o", str(tmp_path / "c.csv")]) == 0
    with open(tmp_path / "c.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["t"]) for r in rows])
    torque = np.array([float(r["motor.T_j"]) for r in rows])
    exact = ladder.Ladder(n).torque(t)
    # 1e-9 of the peak: Newton's tolerance (1e-12 scaled) through the multipliers of 49 bodies, and the CSV's digits
    assert np.max(np.abs(torque - exact)) <= 1e-9 * np.max(np.abs(exact))


@pytest.mark.parametrize("value", ["abc", "0", "-5G", "inf", "1T"])
def test_a_memory_limit_that_is_not_a_size_is_refused_naming_the_variable(value: str, capsys, monkeypatch) -> None:
    monkeypatch.setenv("SYMID_MEMORY_LIMIT", value)
    status, line = refusal(["solve", str(EXAMPLES / "four_bar.toml"), "--steps", "3", "-o", "/dev/null"], capsys)
    assert status == 2 and line == f"symid: SYMID_MEMORY_LIMIT={value!r}: not a memory size (a number of MiB, " \
                                   "or 1500M, 4G)", line


@pytest.mark.slow
def test_a_ladder_past_a_thousand_bodies_solves_on_c_from_the_command_line(tmp_path: Path, monkeypatch) -> None:
    """The ladder of 512 four-bars, 1025 bodies (ng 3075), under the default
    limit (exit 2 were it refused): past the 1000 bodies the reader once
    refused by count, and on every path of the ladder of 1024 (the docs' 2049
    bodies, in twice the time): Phi_q sparse (ng >= SPARSE_MIN), the
    generated C past LARGE_SOURCE (compiled -O1)."""
    monkeypatch.delenv("SYMID_MEMORY_LIMIT", raising=False)
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    n = 512
    path = ladder.write(n, tmp_path / "mech", steps=11)
    assert 2 * n + 1 > 1000 and 6 * n + 3 >= SPARSE_MIN  # its bodies and coordinates
    assert main(["solve", str(path), "--backend", "c", "-o", str(tmp_path / "c.csv")]) == 0
    (source,) = (tmp_path / "cache").glob(f"c-solve-ladder_{n}-*/ladder_{n}_solver.c")
    assert source.stat().st_size >= LARGE_SOURCE
    with open(tmp_path / "c.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 11
    torque = np.array([float(r["motor.T_j"]) for r in rows])
    exact = ladder.Ladder(n).torque(np.array([float(r["t"]) for r in rows]))
    assert np.max(np.abs(torque - exact)) <= 1e-8 * np.max(np.abs(exact))  # 1025 bodies' rounding, CSV digits


@pytest.mark.slow  # a cold numpy setup of 129 bodies in a process of its own: ~7 s
def test_the_numpy_estimate_bounds_the_peak_a_user_run_reaches(tmp_path: Path) -> None:
    """`symid bench` on the ladder of 64 four-bars, cold, as a user runs it: the
    process's peak resident size is below the estimate, and above 80 % of it
    (measured 126-128 MiB against 136: the estimate is a fit, BASE_MB rounded
    up; the module compiled in one piece took 190 MiB). The benchmarks'
    launcher reads the peak: Linux carries a parent's high-water mark into a
    child it forks, and this test's process may be larger than the run."""
    import json
    import os
    import subprocess
    import sys

    import benchmarks.launch

    path = ladder.write(64, tmp_path / "mech", steps=11)
    estimate = footprint.estimate(assemble(api.load_mechanism(path)), "numpy").total_mb
    report = tmp_path / "report.json"
    subprocess.run([sys.executable, benchmarks.launch.__file__, str(report), sys.executable, "-m", "symid", "bench",
                    str(path), "--backend", "numpy", "--instants", "5"], check=True, stdout=subprocess.DEVNULL,
                   env={**os.environ, "SYMID_CACHE": str(tmp_path / "cache")})
    peak = json.loads(report.read_text())["maxrss_mb"]
    assert 0.8 * estimate <= peak <= estimate, (peak, estimate)
