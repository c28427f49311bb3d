"""The results table on every backend: the target path during a run and
under an interrupt, row width against the header for every output subset,
and the rows kept when a run fails part way, each compared with a full
reference run."""

from __future__ import annotations

import contextlib
import io
import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from symid import api, backends
from symid.cli import main
from symid.output.results import write_csv
from cli_files import SLIDER_CRANK, base_text, read_csv, set_line, with_analysis
from tiers import diagonal

REPO = Path(__file__).resolve().parents[2]
BACKENDS = ("numpy", "c", "casadi", "reference")
OLD = "old,table\n1,2\n"


def available(backend: str) -> str:
    """Skip a backend that this machine cannot run (no C compiler, no casadi)."""
    if backend not in backends.names():
        pytest.skip(f"no backend {backend}")
    if backend == "c":
        from symid.backends.c_backend import compiler
        from symid.errors import InputError
        try:
            compiler()
        except InputError:
            pytest.skip("no C compiler")
    return backend


def assert_same_rows(got: np.ndarray, want: np.ndarray) -> None:
    """The same instants (t exactly) and values; the last few instants before
    a failure approach a singular position, where the multipliers grow as the
    condition number does and backends differ in rounding by about as much."""
    assert got.shape == want.shape, "every instant before the failure, none after"
    assert np.array_equal(got[:, 0], want[:, 0])
    # columns that are zero up to rounding (the crank's alpha): absolute, in SI units
    scale = np.maximum(np.max(np.abs(want), axis=0), 1.0)
    diff = np.abs(got - want) / scale
    # (the docstring: to rounding, but the last three instants near the singular position, 1e-3)
    assert np.max(diff[:-3]) <= 1e-9
    assert np.max(diff) <= 1e-3


def temporaries(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.name.endswith(".tmp"))


def solve_cli(tmp_path: Path, capsys, text: str, *extra: str, name: str = "out.csv") -> tuple[int, str, str, Path]:
    path = tmp_path / "mech.toml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / name
    status = main(["solve", str(path), "-o", str(out), *extra])
    captured = capsys.readouterr()
    return status, captured.out, captured.err, out


# -- (a) the target path during a run -------------------------------------------------

@pytest.mark.parametrize("existing", (True, False), ids=("old_file", "no_file"))
def test_target_keeps_its_old_content_until_the_run_ends(tmp_path: Path, existing: bool) -> None:
    """Written to a temporary name and renamed at the end: while rows are
    being produced the target holds the old table (or does not exist), and
    one temporary file sits next to it; after the run, only the new table."""
    out = tmp_path / "out.csv"
    if existing:
        out.write_text(OLD)
    study = api.prepare(SLIDER_CRANK, "numpy", steps=20)
    seen = []

    def watched():
        for values in study.rows():
            seen.append(out.read_text() if out.exists() else None)
            assert len(temporaries(tmp_path)) == 1
            yield values

    assert write_csv(out, study.columns(), watched()) == 20
    assert seen == [OLD if existing else None] * 20
    header, rows = read_csv(out)
    assert header == study.columns() and len(rows) == 20
    assert temporaries(tmp_path) == []


def _preexec() -> None:
    """The child takes SIGINT as a user's Ctrl-C (a background parent may
    ignore it), and cannot fill the disk if the interrupt is missed."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    resource.setrlimit(resource.RLIMIT_FSIZE, (512 << 20, 512 << 20))


# slow: a solve child run until the signal lands; tests/io/test_machine_faults.py keeps a signal mid-run in the
# quick tier
@pytest.mark.slow
def test_sigint_mid_run_keeps_the_old_table_and_leaves_no_temporary(tmp_path: Path) -> None:
    """`symid solve` interrupted while writing rows: exit 130, the old
    table intact, no temporary file left."""
    out = tmp_path / "out.csv"
    out.write_text(OLD)
    env = dict(os.environ, PYTHONPATH=str(REPO), SYMID_CACHE=str(tmp_path / "cache"))
    proc = subprocess.Popen([sys.executable, "-m", "symid", "solve", str(SLIDER_CRANK), "-o", str(out),
                             "--steps", "1000000"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_preexec)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            tmp = temporaries(tmp_path)
            if tmp and tmp[0].stat().st_size > 4096:  # rows are being written
                break
            time.sleep(0.01)
        assert proc.poll() is None, proc.communicate()
        assert out.read_text() == OLD  # mid-run: the target is untouched
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == [f"symid: interrupted; {out} not written"]
    assert out.read_text() == OLD
    assert temporaries(tmp_path) == []


# -- (b) output subsets on every backend -------------------------------------------------

SUBSETS = {
    "only_q": 'outputs = ["q"]',
    "one_reaction": 'reactions = ["motor"]',
    "reactions_and_q": 'outputs = ["reactions", "q"]\nreactions = ["motor", "main_bearing"]',
    "kinematics": 'kind = "kinematics"',
}


@pytest.fixture(scope="module")
def full_reference(tmp_path_factory) -> tuple[list[str], np.ndarray, list[str]]:
    """The bundled slider-crank's full table and summary lines, reference backend."""
    folder = tmp_path_factory.mktemp("full")
    out = folder / "full.csv"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
        assert main(["solve", str(SLIDER_CRANK), "-o", str(out), "--steps", "21", "--backend", "reference"]) == 0
    header, rows = read_csv(out)
    return header, np.array(rows, dtype=float), summary_lines(stdout.getvalue())


def summary_lines(stdout: str) -> list[str]:
    """The per-driver summary lines of `symid solve` (after the file's line)."""
    return [line for line in stdout.splitlines() if re.match(r"^\w+: peak ", line)]


@pytest.mark.parametrize("subset, backend", diagonal(sorted(SUBSETS), BACKENDS))
def test_output_subset_rows_are_as_wide_as_the_header_and_equal_the_full_run(
        tmp_path: Path, capsys, backend: str, subset: str, full_reference) -> None:
    available(backend)
    text = base_text()
    if subset == "kinematics":
        text = set_line(text, "kind", '"kinematics"')
    else:
        text = with_analysis(text, SUBSETS[subset])
    status, stdout, err, out = solve_cli(tmp_path, capsys, text, "--steps", "21", "--backend", backend)
    assert status == 0, err
    lines = out.read_text().splitlines()
    header = lines[0].split(",")
    assert len(lines) == 22
    assert all(len(line.split(",")) == len(header) for line in lines[1:]), "a row wider or narrower than the header"
    full_header, full, full_summary = full_reference
    assert set(header) <= set(full_header) and header[0] == "t"
    data = np.array([line.split(",") for line in lines[1:]], dtype=float)
    want = full[:, [full_header.index(c) for c in header]]
    scale = np.maximum(np.max(np.abs(want), axis=0), 1.0)  # absolute for near-zero columns
    # every output subset solves the same equations to tol 1e-12: rounding, 1 as the floor of near-zero columns
    assert np.max(np.abs(data - want) / scale) <= 1e-10
    # the summary: the same figures as the full run's wherever the driver's columns are kept
    if "motor.T_j" in header:
        assert summary_lines(stdout) == full_summary and full_summary
    else:
        assert not any(" 0 N" in line for line in summary_lines(stdout))


# -- (c) a run failing part way, on every backend -----------------------------------------

def _failing_text() -> str:
    """A rod (0.05) shorter than the crank (0.1): no position past 30 degrees
    of crank, i.e. t = 1/60 s."""
    return set_line(base_text(), "L_rod", "0.05")


@pytest.fixture(scope="module")
def failing_reference(tmp_path_factory) -> np.ndarray:
    """The reference backend's rows of the failing run (201 steps over 0.2 s)."""
    folder = tmp_path_factory.mktemp("failing")
    path = folder / "mech.toml"
    path.write_text(_failing_text(), encoding="utf-8")
    result = api.solve(path, backend="reference")
    assert result.error is not None
    return result.data


@pytest.mark.parametrize("backend", BACKENDS)
def test_failure_part_way_keeps_every_instant_before_it_equal_to_the_reference(
        tmp_path: Path, capsys, backend: str, failing_reference: np.ndarray) -> None:
    available(backend)
    status, _, err, out = solve_cli(tmp_path, capsys, _failing_text(), "--backend", backend)
    assert status == 3, err
    header, rows = read_csv(out)
    assert_same_rows(np.array(rows, dtype=float), failing_reference)
    t_fail = float(re.search(r"t = ([-+0-9.eE]+)", err).group(1))
    assert t_fail == pytest.approx(len(rows) * 0.2 / 200, abs=1e-15)
    assert f"the {len(rows)} instants before it" in err
    assert temporaries(tmp_path) == []


@pytest.mark.parametrize("backend", BACKENDS)
def test_failure_part_way_in_a_later_chunk_keeps_the_chunks_rows(tmp_path: Path, capsys, backend: str) -> None:
    """The same failure on a grid of 1301 instants over 0.02 s, so that it
    falls after the C solver's first chunk (1024 instants): the failing
    chunk's solved rows are kept too, as the NumPy backend keeps them."""
    available(backend)
    if backend in ("numpy", "reference"):
        pytest.skip("numpy is the comparison (its module loop has no chunks); the reference is slow here")
    extra = ("--t1", "0.02", "--steps", "1301")
    status, _, err, out = solve_cli(tmp_path, capsys, _failing_text(), *extra, "--backend", backend)
    assert status == 3, err
    data = np.array(read_csv(out)[1], dtype=float)
    assert len(data) > 1024
    status, _, err2, want_path = solve_cli(tmp_path, capsys, _failing_text(), *extra, "--backend", "numpy",
                                           name="numpy.csv")
    assert status == 3, err2
    assert_same_rows(data, np.array(read_csv(want_path)[1], dtype=float))
    assert temporaries(tmp_path) == []
