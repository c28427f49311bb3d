"""Run plans (`symid.tools.plan`): a repeated `symid solve` skips sympy and gives
the same table, messages and exit status as the normal path; any change to
its inputs, or any doubt about the plan, takes the normal path."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid import cli
from symid.cli import solve as solve_command

from symid.tools import plan
from symid.errors import AnalysisError
from tiers import first_quick

REPO = Path(__file__).resolve().parents[2]
SLIDER_CRANK = api.example("slider_crank")
TABLED = 'f = { table = "motion.csv", column = "angle" }'
# Imports a planned run must not make (the point of a plan: no derivation).
HEAVY = ("sympy", "jinja2", "symid.model.mechanism", "symid.symbolic.assemble", "symid.symbolic.derive", "symid.codegen.model")


def backends_here() -> list[str]:
    return ["numpy", "c"] if shutil.which(os.environ.get("CC") or "cc") or shutil.which("gcc") else ["numpy"]


def run_subprocess(args: list[str], cwd: Path, cache: Path) -> tuple[subprocess.CompletedProcess, list[str]]:
    """`symid` main() in a fresh interpreter; also returns the heavy modules it imported."""
    code = ("import sys, json\nfrom symid.cli import main\nstatus = main(sys.argv[1:])\n"
            f"print(json.dumps([m for m in sys.modules if m.startswith({HEAVY!r})]), file=sys.stderr)\n"
            "raise SystemExit(status)")
    env = {**os.environ, "SYMID_CACHE": str(cache), "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)
    *err, modules = proc.stderr.splitlines()
    proc.stderr = "".join(line + "\n" for line in err)
    return proc, json.loads(modules)


@pytest.mark.parametrize("backend", first_quick(backends_here()))  # one planner; c: the slow tier
def test_warm_run_imports_no_sympy_and_repeats_the_cold_run(tmp_path, backend):
    """Same CSV bytes, stdout, stderr (with a warning) and exit status as the
    normal path; the warm run never imports sympy."""
    cache = tmp_path / "cache"
    args = ["solve", str(SLIDER_CRANK), "--steps", "41", "--backend", backend, "-o", "out.csv"]
    if backend == "numpy":
        args += ["--cond-warn", "1.5", "--cond"]  # a warning on stderr and an extra column
    cold, cold_modules = run_subprocess(args, tmp_path, cache)
    assert cold.returncode == 0, cold.stderr
    assert "sympy" in cold_modules
    cold_csv = (tmp_path / "out.csv").read_bytes()
    (tmp_path / "out.csv").unlink()
    assert list((cache / "plans").glob("*.json")), "a successful run leaves a plan"
    warm, warm_modules = run_subprocess(args, tmp_path, cache)
    assert warm_modules == []
    assert (warm.returncode, warm.stdout, warm.stderr) == (cold.returncode, cold.stdout, cold.stderr)
    assert (tmp_path / "out.csv").read_bytes() == cold_csv
    if backend == "numpy":
        assert "symid: warning: Phi_q is ill-conditioned" in warm.stderr


@pytest.fixture
def spy(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The files of the runs that took the normal path."""
    normal: list[str] = []
    original = solve_command._solve

    def counting(args, key):  # type: ignore[no-untyped-def]
        normal.append(args.file)
        return original(args, key)

    monkeypatch.setattr(solve_command, "_solve", counting)
    return normal


def solve(folder: Path, capsys: pytest.CaptureFixture[str], *extra: str, file: str = "m.toml",
          ) -> tuple[int, str, str, bytes]:
    out = folder / "out.csv"
    status = cli.main(["solve", str(folder / file), "--steps", "21", "-o", str(out), *extra])
    captured = capsys.readouterr()
    return status, captured.out, captured.err, out.read_bytes() if out.exists() else b""


def test_second_identical_run_is_planned_and_identical(tmp_path, capsys, spy):
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys)
    assert len(spy) == 1 and first[0] == 0
    second = solve(tmp_path, capsys)
    assert len(spy) == 1, "the second run should use the plan"
    assert second == first


def test_editing_the_file_misses(tmp_path, capsys, spy):
    path = tmp_path / "m.toml"
    path.write_text(SLIDER_CRANK.read_text())
    before = solve(tmp_path, capsys)
    path.write_text(SLIDER_CRANK.read_text().replace("F_gas = 100.0", "F_gas = 200.0"))
    after = solve(tmp_path, capsys)
    assert len(spy) == 2
    assert after[3] != before[3] and after[1] != before[1]  # the load and so the torque changed
    assert solve(tmp_path, capsys) == after and len(spy) == 2


def test_set_values_miss(tmp_path, capsys, spy):
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    base = solve(tmp_path, capsys)
    changed = solve(tmp_path, capsys, "--set", "F_gas=50")
    assert len(spy) == 2 and changed[3] != base[3]
    assert solve(tmp_path, capsys, "--set", "F_gas=50") == changed and len(spy) == 2
    assert solve(tmp_path, capsys) == base and len(spy) == 2


@pytest.mark.parametrize("option", [["--steps", "22"], ["--t1", "0.1"], ["--kind", "kinematics"], ["--tol", "1e-10"]])
def test_run_options_miss(tmp_path, capsys, spy, option):
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    solve(tmp_path, capsys)
    solve(tmp_path, capsys, *option)
    assert len(spy) == 2


def write_motion(folder: Path, ripple: float) -> None:
    t = np.linspace(0.0, 0.2, 81)
    y = 2 * np.pi * 5 * t + ripple * np.sin(2 * np.pi * 5 * t)
    (folder / "motion.csv").write_text("time,angle\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, y)))


def test_editing_a_referenced_table_misses(tmp_path, capsys, spy):
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text().replace('f = "omega*t"', TABLED))
    write_motion(tmp_path, 0.1)
    before = solve(tmp_path, capsys)
    assert before[0] == 0 and solve(tmp_path, capsys) == before and len(spy) == 1
    write_motion(tmp_path, 0.2)
    after = solve(tmp_path, capsys)
    assert len(spy) == 2 and after[3] != before[3]


def test_symid_sources_are_part_of_the_key(tmp_path, capsys, spy, monkeypatch):
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    solve(tmp_path, capsys)
    monkeypatch.setattr(plan, "code_version", lambda: "another version of symid")
    solve(tmp_path, capsys)
    assert len(spy) == 2


def test_code_version_follows_an_edit_of_the_sources(tmp_path):
    copy = tmp_path / "symid"
    shutil.copytree(REPO / "symid", copy, ignore=shutil.ignore_patterns("__pycache__"))
    code = "import symid.codegen.sources as s; print(s.__file__, s.code_version())"

    def version() -> str:
        env = {**os.environ, "PYTHONPATH": str(tmp_path)}
        return subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True,
                              text=True, check=True).stdout

    before = version()
    assert before.startswith(str(copy))
    with open(copy / "solve.py", "a") as f:
        f.write("# an edit\n")
    assert version() != before


def plans(folder: Path) -> list[Path]:
    return sorted((folder / "plans").glob("*.json"))


def test_a_corrupt_plan_takes_the_normal_path(tmp_path, capsys, spy, monkeypatch):
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys)
    (stored,) = plans(tmp_path / "cache")
    stored.write_text(stored.read_text()[:100])
    assert solve(tmp_path, capsys) == first and len(spy) == 2
    assert json.loads(stored.read_text())["format"] == plan.FORMAT, "the normal path wrote it again"


def test_a_plan_altered_into_valid_json_takes_the_normal_path(tmp_path, capsys, spy, monkeypatch):
    """Found trying symid as a new user: a plan edited or damaged into other
    valid JSON (a parameter's value changed) is checked like every other cache
    entry, so it never gives other numbers with exit status 0."""
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys, "--backend", "numpy")
    (stored,) = plans(tmp_path / "cache")
    data = json.loads(stored.read_text())
    data["params"]["m_slider"] *= 3.0  # a damaged digit: still a plan, other physics
    stored.write_text(json.dumps(data))
    assert solve(tmp_path, capsys, "--backend", "numpy") == first, "a damaged plan must not change the table"
    assert len(spy) == 2, "the damaged plan is distrusted: the normal path ran"


def test_a_missing_solver_takes_the_normal_path(tmp_path, capsys, spy, monkeypatch):
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys)
    (stored,) = plans(tmp_path / "cache")
    shutil.rmtree(Path(json.loads(stored.read_text())["artifact"]).parent)
    assert solve(tmp_path, capsys) == first and len(spy) == 2


def test_a_planned_run_that_fails_reruns_the_normal_path(tmp_path, capsys, spy, monkeypatch):
    """Nothing of the failed attempt shows: same file, output and status."""
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys)

    def failing(*args, **kwargs):  # type: ignore[no-untyped-def]
        yield np.zeros(67)
        raise AnalysisError("Newton did not converge", 0.01, 1)

    monkeypatch.setattr(plan, "table_blocks", failing)
    assert solve(tmp_path, capsys) == first and len(spy) == 2
    assert len(plans(tmp_path / "cache")) == 1, "the normal path stored the plan again"


def test_a_failed_run_leaves_no_plan(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text().replace("L_rod = 0.3 ", "L_rod = 0.05"))
    status, _, err, _ = solve(tmp_path, capsys)
    assert status == 3, err
    assert plans(tmp_path / "cache") == []


@pytest.mark.slow  # a planned solve with its figures; the planned runs' other tests stay in the quick tier
def test_plots_take_the_normal_path(tmp_path, capsys, spy):
    pytest.importorskip("matplotlib")
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    solve(tmp_path, capsys)
    solve(tmp_path, capsys, "--plot")
    assert len(spy) == 2


# slow: a child that draws a table and reads a sweep's (seconds cold); test_warm_run_imports_no_sympy keeps a
# sympy-free child in the quick tier
@pytest.mark.slow
def test_a_table_plotted_alone_imports_no_sympy(tmp_path, capsys):
    """`symid plot TABLE` without --mechanism draws from the table only: neither a
    results table nor a sweep table needs the reader, the mechanism or sympy (the
    sweep table read and its plot module imported, not drawn: its figure takes a second)."""
    pytest.importorskip("matplotlib")
    run = ["solve", str(SLIDER_CRANK), "--steps", "21", "--backend", "numpy", "-o", str(tmp_path / "run.csv")]
    sweep = ["sweep", str(SLIDER_CRANK), "--grid", "L_rod=0.25:0.4:2", "--steps", "21", "--backend", "numpy",
             "-o", str(tmp_path / "sw.csv")]
    assert cli.main(run) == 0 and cli.main(sweep) == 0
    capsys.readouterr()
    code = ("import sys, json\nfrom symid.cli import main\nfrom symid.cli import plot\n"
            "from symid.output import sweep_plot\nfrom symid.study.table import read\n"
            "status = [main(['plot', 'run.csv', '-o', 'figures']), plot._is_sweep(plot.Path('sw.csv')),"
            " len(read('sw.csv').values)]\n"
            f"print(json.dumps([status, [m for m in sys.modules if m.startswith({HEAVY!r})]]))")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    status, modules = json.loads(proc.stdout.splitlines()[-1])
    assert status == [0, True, 2], proc.stderr
    assert modules == []
    assert sorted(p.name for p in (tmp_path / "figures").iterdir()) == ["run_reactions.png"]


def test_an_output_error_on_a_planned_run_is_the_same_input_error(tmp_path, capsys, spy):
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    solve(tmp_path, capsys)
    args = ["solve", str(tmp_path / "m.toml"), "--steps", "21", "-o", str(tmp_path / "missing" / "out.csv")]
    planned = cli.main(args), capsys.readouterr()
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text() + "\n")  # a miss: the normal path
    normal = cli.main(args), capsys.readouterr()
    assert len(spy) == 1  # neither run solved: the missing folder is refused before either path
    assert planned == normal and planned[0] == 2 and "no folder" in planned[1].err


def test_summary_inputs_for_other_instants_are_evaluated_again(tmp_path, capsys, spy, monkeypatch):
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys)
    (stored,) = plans(tmp_path / "cache")
    data = json.loads(stored.read_text())
    data["summary"][0]["t"][3] += 1e-9
    data["summary"][0]["f"] = [0.0] * len(data["summary"][0]["f"])  # would give another line if used
    del data["sha256"]  # sealed again: this test is about the plan's own check of its instants
    stored.write_text(json.dumps({**data, "sha256": plan._digest(json.dumps(data, sort_keys=True).encode())}))
    assert solve(tmp_path, capsys) == first and len(spy) == 1
