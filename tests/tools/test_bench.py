"""The benchmark never rots: `symid bench`, the ladder's closed form, the
harness (`python -m benchmarks`: its list, its errors, its JSON) and a smoke
run (tiny sizes) of every case it registers. No timing assertions."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from symid import api
from symid.cli import main

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import ladder  # noqa: E402
from benchmarks.cases import Case, load_all  # noqa: E402
from benchmarks.run import flat, parser_for  # noqa: E402

CASES = load_all()


def harness(*args: str, cwd: Path = ROOT, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """`python -m benchmarks ARGS` as a user runs it (no deadline: under load a smoke run takes minutes)."""
    if env is not None:
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]), **env}
    return subprocess.run([sys.executable, "-m", "benchmarks", *args], cwd=cwd, capture_output=True, text=True,
                          env=env)


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


def test_list_names_every_registered_case_once() -> None:
    done = harness("--list")
    assert done.returncode == 0, done.stderr
    listed = [line.split()[0] for line in done.stdout.splitlines()]
    assert listed == sorted(CASES) and len(CASES) >= 13
    # every case module under benchmarks/cases registers what --list shows: none is left out by an import
    assert {"overview", "scale", "stability", "instructions", "mutation"} <= set(listed)


def test_the_registry_read_from_the_sources_is_what_the_modules_register() -> None:
    # load_all reads each module's @register line without importing it: once imported,
    # every module registers the same cases with the same summary, tools, options and report
    import importlib
    import pkgutil

    from benchmarks import cases as package

    for info in pkgutil.iter_modules(package.__path__):
        importlib.import_module(f"benchmarks.cases.{info.name}")
    assert sorted(package.CASES) == sorted(CASES)
    for name, case in CASES.items():
        own = package.CASES[name]
        assert (case.summary, case.tools) == (own.summary, own.tools), name
        assert (case.options is None, case.report is None) == (own.options is None, own.report is None), name


def test_docs_describe_every_case_and_only_registered_ones() -> None:
    import re

    page = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    described = re.findall(r"^\| `(\w+)` \|", page, re.M)
    assert sorted(described) == sorted(CASES)
    for name, case in CASES.items():  # and the options each row lists are the case's own
        row = next(line for line in page.splitlines() if line.startswith(f"| `{name}` |"))
        options = parser_for(CASES, name).format_help().split()
        for option in re.findall(r"`(--?[\w-]+)", row.rsplit("|", 2)[-2]):
            assert option in options, (name, option)


def test_stdout_closed_early_ends_quietly() -> None:
    read, write = os.pipe()
    os.close(read)  # a reader gone before the first line (`| head -0`): every write fails
    try:
        done = subprocess.run([sys.executable, "-m", "benchmarks", "--list"], cwd=ROOT, stdout=write,
                              stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write)
    assert (done.returncode, done.stderr) == (141, "")


def _with(text: str) -> list[int]:
    """Processes whose command line holds text."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            if entry.name.isdigit() and text in (entry / "cmdline").read_bytes().decode(errors="replace"):
                found.append(int(entry.name))
        except OSError:  # gone meanwhile
            pass
    return found


@pytest.mark.skipif(not Path("/proc/self/cmdline").is_file(), reason="reads /proc")
@pytest.mark.skipif(shutil.which("gcc") is None, reason="the scale case needs gcc")
def test_sigterm_stops_the_workers_and_says_so_in_one_line(tmp_path: Path) -> None:
    import signal
    import time

    env = {**os.environ, "TMPDIR": str(tmp_path),  # the scratch folder, and so each worker's spec, under tmp_path
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "benchmarks", "scale", "--smoke", "--out", str(tmp_path / "out")],
                            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        while not [p for p in _with(str(tmp_path)) if p != proc.pid] and proc.poll() is None:
            time.sleep(0.05)  # until its worker runs (a cold ladder's setup: seconds)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 143
    assert err == "python -m benchmarks scale: interrupted; nothing written\n"
    left = {p: (Path(f"/proc/{p}/stat").read_text()[:120], Path(f"/proc/{p}/cmdline").read_bytes()[:200])
            for p in _with(str(tmp_path)) if Path(f"/proc/{p}").exists()}
    assert left == {}  # no worker left running
    assert list(tmp_path.iterdir()) == []  # nor its scratch folder


def test_an_unknown_case_is_one_line_and_exit_2() -> None:
    done = harness("no_such_case", "--smoke")
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "no_such_case" in done.stderr and "overview" in done.stderr


def test_a_missing_program_is_one_line_and_exit_2(tmp_path: Path) -> None:
    done = harness("friction", "--smoke", "--out", str(tmp_path), env={"PATH": str(tmp_path)})  # no gcc there
    assert done.returncode == 2
    assert done.stderr == "python -m benchmarks friction: needs gcc, not installed\n"
    assert not list(tmp_path.iterdir())


@pytest.mark.slow  # a harness child; the harness's list and errors stay in the quick tier
def test_a_run_that_fails_is_one_line_and_exit_3(tmp_path: Path) -> None:
    done = harness("optimize", "--smoke", "--backend", "no_such_backend", "--out", str(tmp_path))
    assert done.returncode == 3, done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("python -m benchmarks optimize: failed: ")
    assert "Traceback" not in done.stderr and not list(tmp_path.iterdir())


def test_a_case_option_is_the_cases_own() -> None:
    assert "--ladders" in parser_for(CASES, "scale").format_help().split()
    assert "--ladders" not in parser_for(CASES, "friction").format_help().split()
    done = harness("scale", "--help")  # and the command line shows it
    assert done.returncode == 0 and "--ladders" in done.stdout


def test_a_smoke_runs_workers_share_its_cache_and_leave_it_there(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse

    from benchmarks.run import Context

    cache, work = tmp_path / "cache", tmp_path / "work"
    cache.mkdir()
    work.mkdir()
    (cache / "entry").write_text("")
    monkeypatch.setenv("SYMID_CACHE", str(cache))  # the run's cache, as the harness leaves it set
    smoke, full = (Context("x", s, argparse.Namespace(), work, None) for s in (True, False))
    assert smoke.env()["SYMID_CACHE"] == smoke.env(work / "own")["SYMID_CACHE"] == str(cache)
    assert full.env(work / "own")["SYMID_CACHE"] == str(work / "own")
    got = smoke.isolated("json:loads", '{"a": 1}', 120)  # a worker: `python -m benchmarks --worker`
    assert got.status == "ok" and got.result["a"] == 1, got
    assert (cache / "entry").is_file()  # the shared cache outlives the worker
    fresh = Path(full.env()["SYMID_CACHE"])  # a full run's worker: a fresh, empty folder of its own
    assert fresh.parent == work and fresh != cache and list(fresh.iterdir()) == []


def test_flat_lists_every_scalar_by_its_dotted_key() -> None:
    figures = {"a": 1.5, "b": {"c": 2, "d": [1, {"k": 2.5}], "e": {"f": "x", "g": None}}, "h": True}
    assert flat(figures) == [("a", 1.5), ("b.c", 2), ("b.d.0", 1), ("b.d.1.k", 2.5), ("b.e.f", "x"),
                             ("b.e.g", None), ("h", True)]


def _smoke(case: Case) -> Any:
    marks = [pytest.mark.slow]  # each runs a benchmark (the marker's definition), 5 s to minutes under load
    missing = [t for t in case.tools if shutil.which(t) is None]
    if missing:
        marks.append(pytest.mark.skip(reason=f"needs {', '.join(missing)}"))
    return pytest.param(case.name, marks=marks, id=case.name)


@pytest.mark.parametrize("name", [_smoke(c) for c in CASES.values() if c.name != "overview"])
def test_every_case_runs_in_smoke_mode_and_writes_its_json(name: str, tmp_path: Path) -> None:
    (tmp_path / "tmp").mkdir()
    done = harness(name, "--smoke", "--out", str(tmp_path / "out"), cwd=tmp_path, env={"TMPDIR": str(tmp_path / "tmp")})
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads((tmp_path / "out" / f"{name}.json").read_text())
    assert result["case"] == name and result["smoke"] is True
    assert result["machine"]["cpu_count"] >= 1 and result["run_s"] > 0
    assert result["machine"]["numpy"] == np.__version__  # read from the package's metadata, not by importing it
    figures = flat(result["figures"])
    assert figures, "a case returns figures"
    # the figures are printed, one dotted key a line
    key, _ = figures[0]
    assert f"{key}: " in done.stdout
    # nothing left behind where it ran, nor in the temporary folder (the harness's scratch, removed)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "tmp"]
    assert list((tmp_path / "tmp").iterdir()) == []


@pytest.mark.slow  # the overview, every approach at tiny sizes
def test_overview_smoke_run_writes_every_output(tmp_path: Path) -> None:
    done = harness("overview", "--smoke", "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr[-2000:]
    for name in ("overview.json", "overview.md", "time_vs_ng.png", "time_vs_error.png", "tolerance_sweep.png"):
        assert (tmp_path / name).is_file(), name
    result = json.loads((tmp_path / "overview.json").read_text())["figures"]
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
    assert "| approach |" in (tmp_path / "overview.md").read_text()
    # the design study beside CasADi's C loop and CasADi's map from Python (issue 14)
    study = result["study"]
    assert study["status"] == "ok", study
    assert study["grid"]["threads_2"]["failed"] == 0 and study["grid"]["threads_2"]["instants_per_s"] > 0
    assert study["casadi_map"]["us_per_instant"] > 0 and study["casadi_c"]["us_per_instant_1_thread"] > 0
    assert 'Function.map(K, "thread", 2)' in (tmp_path / "overview.md").read_text()


@pytest.mark.slow  # a ladder solved far from the origin; the ladder's closed form stays in the quick tier
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
