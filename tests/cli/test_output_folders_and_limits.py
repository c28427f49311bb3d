"""Faults a new user meets on the study and export paths, tried after issue 32
was built (its "Done when"): a limit the optimizer cannot meet is named, not
hidden behind SLSQP's line-search message; an output whose folder is a file is
said to be one; an output in a folder this user cannot write is refused before
any solver is generated, compiled or run, not after the study."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from tiers import first_quick

REPO = Path(__file__).resolve().parents[2]
CRANK = str(api.example("slider_crank"))
STEPS = "11"
TIMEOUT = 600


def test_a_limit_that_cannot_be_met_is_named_with_its_value(tmp_path, capsys, monkeypatch):
    """crank_pin.force_peak <= 1 N cannot hold for any rod: at t = 0 (outer dead
    centre) crank and rod lie on the x axis with no vertical acceleration and no
    angular acceleration of the rod, so the rod's weight m_rod*g = 9.81 N is
    shared equally by its two pins: the crank pin carries at least 4.905 N.
    The line names the limit, the figure where the optimizer stopped and the
    bounds, and nothing is written (exit 3)."""
    monkeypatch.chdir(tmp_path)
    status = main(["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.5",
                   "--subject-to", "crank_pin.force_peak<=1", "--steps", STEPS, "--backend", "numpy",
                   "-o", "best.toml"])
    err = capsys.readouterr().err
    assert status == 3, err
    assert err.count("\n") == 1 and "Traceback" not in err
    found = re.search(r"with a limit not met: crank_pin\.force_peak = (\S+) \(<= 1\)", err)
    assert found, err
    assert float(found.group(1)) >= 9.81 * 1.0 / 2
    assert "--vary bounds" in err and "nothing written" in err
    assert not Path("best.toml").exists()


def test_a_limit_that_can_be_met_still_converges(tmp_path, capsys, monkeypatch):
    """The unmet-limit line is not said of a feasible limit: with 1000 N on the
    crank pin (far above the ~250 N the slider-crank reaches) it converges."""
    monkeypatch.chdir(tmp_path)
    status = main(["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.5",
                   "--subject-to", "crank_pin.force_peak<=1000", "--steps", STEPS, "--backend", "numpy",
                   "-o", "best.toml"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert "not met" not in captured.err and Path("best.toml").is_file()


@pytest.mark.parametrize("command", [
    ["sweep", CRANK, "--grid", "L_rod=0.3:0.4:2", "--backend", "numpy"],
    ["solve", CRANK],
])
def test_an_output_under_a_file_says_the_file_is_not_a_folder(tmp_path, capsys, command):
    (tmp_path / "afile").write_text("")
    out = tmp_path / "afile" / "out.csv"
    status = main([*command, "--steps", STEPS, "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert f"{tmp_path / 'afile'} is a file, not a folder" in err


def unprivileged() -> list[str]:
    """The prefix that runs a command without root's power to write any folder."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: a read-only folder cannot be made")
    return [setpriv, "--inh-caps=-all", "--bounding-set=-all"]


@pytest.mark.parametrize("command", [
    ["solve", CRANK, "--backend", "c", "-o", "{ro}/run.csv"],
    ["solve", CRANK, "--backend", "c", "-o", "{ro}/run.parquet"],
    ["sweep", CRANK, "--grid", "L_rod=0.3:0.4:2", "--backend", "c", "-o", "{ro}/study.csv"],
    ["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.5", "--backend", "c",
     "-o", "{ro}/best.toml"],
], ids=["solve-csv", "solve-parquet", "sweep", "optimize"])
def test_a_read_only_output_folder_is_refused_before_any_work(tmp_path, command):
    """A real read-only folder (mode 555, the command run without root's
    override): exit 2 naming the folder, and the empty cache proves no solver
    was generated or compiled (the study did not run only to be lost)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    cache = tmp_path / "cache"
    args = [a.replace("{ro}", str(ro)) for a in command]
    ro.chmod(0o555)
    try:
        done = subprocess.run([*unprivileged(), sys.executable, "-m", "symid", *args, "--steps", STEPS],
                              capture_output=True, text=True, timeout=TIMEOUT, cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": str(REPO), "SYMID_CACHE": str(cache)})
    finally:
        ro.chmod(0o755)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert f"cannot write: the folder {ro} is not writable by this user" in done.stderr
    assert not any(cache.glob("c-*")), sorted(p.name for p in cache.iterdir())
    assert list(ro.iterdir()) == []


def test_the_default_output_in_a_read_only_folder_is_refused_before_the_solve(tmp_path):
    """No -o: `<name>.csv` in the current folder, read-only here; exit 2 naming
    the folder (said only by the check before the solve, not by the writer)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        done = subprocess.run([*unprivileged(), sys.executable, "-m", "symid", "solve", CRANK, "--steps", STEPS,
                               "--backend", "numpy"], capture_output=True, text=True, timeout=TIMEOUT, cwd=ro,
                              env={**os.environ, "PYTHONPATH": str(REPO)})
    finally:
        ro.chmod(0o755)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert "slider_crank.csv: cannot write: the folder . is not writable by this user" in done.stderr
    assert list(ro.iterdir()) == []


@pytest.mark.parametrize("table", ["results", "sweep"])
def test_plot_into_a_file_says_it_is_a_file_not_a_folder(tmp_path, capsys, table):
    """`symid plot -o afile` said "afile: File exists"; below a file, "Not a directory"."""
    data = tmp_path / f"{table}.csv"
    if table == "results":
        assert main(["solve", CRANK, "--steps", STEPS, "--backend", "numpy", "-o", str(data)]) == 0
        extra = ["--mechanism", CRANK]
    else:
        assert main(["sweep", CRANK, "--grid", "L_rod=0.3:0.4:2", "--steps", STEPS, "--backend", "numpy",
                     "-o", str(data)]) == 0
        extra = []
    afile = tmp_path / "afile"
    afile.write_text("mine")
    capsys.readouterr()
    for target in (afile, afile / "sub"):
        status = main(["plot", str(data), *extra, "-o", str(target)])
        err = capsys.readouterr().err
        assert status == 2 and err.count("\n") == 1, err
        assert f"{target}: cannot write: {afile} is a file, not a folder" in err
    assert afile.read_text() == "mine"


@pytest.mark.parametrize("command", first_quick([
    (["solve", CRANK, "--set", "F_gas=1e308", "-o", "run.csv"],),
    (["sweep", CRANK, "--grid", "F_gas=1e300:1e308:2", "-o", "study.csv"],),
], keep=1, ids=["solve", "sweep"]))
def test_a_power_past_the_largest_double_is_no_numpy_warning(tmp_path, command):
    """F_gas = 1e308 N on the piston: the motor torque is ~1e307 N·m and its
    power T*omega (omega = 10*pi rad/s) passes 1.8e308, the largest double.
    The run says so by its value (inf), not by a NumPy RuntimeWarning naming a
    source line on stderr (a subprocess: warnings as a user sees them)."""
    done = subprocess.run([sys.executable, "-m", "symid", *command, "--steps", STEPS, "--backend", "numpy"],
                          capture_output=True, text=True, timeout=TIMEOUT, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert done.returncode == 0, done.stderr
    assert "Warning" not in done.stderr and ".py:" not in done.stderr, done.stderr


@pytest.mark.parametrize("plot_dir", ["afile", "afile/sub"])
def test_a_plot_dir_that_is_a_file_is_refused_before_the_table_is_written(tmp_path, capsys, plot_dir):
    """`--plot-dir afile` wrote the table, then failed at the pictures: now
    refused before the run, naming the file in the way, and no table written."""
    (tmp_path / "afile").write_text("mine\n")
    out = tmp_path / "out.csv"
    status = main(["solve", CRANK, "--steps", STEPS, "-o", str(out), "--plot-dir", str(tmp_path / plot_dir)])
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err and err.count("\n") == 1, err
    assert f"{tmp_path / 'afile'} is a file, not a folder" in err, err
    assert not out.exists() and (tmp_path / "afile").read_text() == "mine\n"
