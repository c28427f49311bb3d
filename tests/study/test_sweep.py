"""`symid sweep`: every variant's figures equal those of its own `symid solve --set`
table (computed here from the table's columns, not by symid's summary), the table's
format (17 digits, Parquet round trip), failed variants kept, exit statuses, Ctrl-C."""

from __future__ import annotations

import csv
import math
import os
import pty
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.study import table as sweep_table
from symid.study import design as vary
from shell import default_signals

REPO = Path(__file__).resolve().parents[2]
CRANK = str(api.example("slider_crank"))
STEPS = "21"
JOINTS = ("main_bearing", "crank_pin", "wrist_pin", "cylinder_guide", "motor")
FIGURES = ["motor.effort_peak", "motor.effort_t_peak", "motor.effort_rms", "motor.power_peak",
           *(f"{j}.force_peak" for j in JOINTS)]
BACKENDS = ("c", "numpy")


def read_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def sweep(tmp_path: Path, capsys, *args: str, out: str = "sweep.csv") -> tuple[int, str, str]:
    status = main(["sweep", CRANK, "--steps", STEPS, "-o", str(tmp_path / out), *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def truth(tmp_path: Path, capsys, backend: str, values: dict[str, str]) -> tuple[dict[str, float], str, float]:
    """The figures of one `symid solve --set` table, from its columns: the motor's torque
    `motor.T_j`, its power T_j * omega (f = omega t, omega = 2 pi n), the reaction forces."""
    out = tmp_path / f"solve_{len(list(tmp_path.iterdir()))}.csv"
    sets = [a for name, value in values.items() for a in ("--set", f"{name}={value}")]
    status = main(["solve", CRANK, "--steps", STEPS, "--backend", backend, "-o", str(out), *sets])
    capsys.readouterr()
    header, rows = read_rows(out)
    data = np.array(rows, dtype=float).reshape(len(rows), len(header))
    col = {c: data[:, k] for k, c in enumerate(header)}
    t, torque = col["t"], col["motor.T_j"]
    n = float(values.get("n", "5"))
    power = torque * 2 * math.pi * n
    k = int(np.argmax(np.abs(torque)))
    span = t[-1] - t[0]
    rms = math.sqrt(float(np.sum((torque[1:] ** 2 + torque[:-1] ** 2) * np.diff(t))) / 2 / span) if span else math.nan
    figures = {"motor.effort_peak": abs(torque[k]), "motor.effort_t_peak": t[k], "motor.effort_rms": rms,
               "motor.power_peak": float(np.max(np.abs(power)))}
    for joint in JOINTS:
        roles = [c.rpartition("_")[2] for c in header if c.startswith(f"{joint}.Fx_")]
        figures[f"{joint}.force_peak"] = max(float(np.max(np.hypot(col[f"{joint}.Fx_{r}"], col[f"{joint}.Fy_{r}"])))
                                             for r in roles)
    return figures, "ok" if status == 0 else "failed", float(t[-1]) if len(t) else math.nan


def assert_rows_match_solves(tmp_path, capsys, path: Path, params: list[str], backend: str) -> None:
    header, rows = read_rows(path)
    assert header == ["variant", *params, "status", "t_end", *FIGURES, "cond_worst"]
    for k, row in enumerate(rows):
        cells = dict(zip(header, row))
        assert cells["variant"] == str(k)
        expected, status, t_end = truth(tmp_path, capsys, backend, {p: cells[p] for p in params})
        assert (cells["status"] == "ok") == (status == "ok"), row
        assert float(cells["t_end"]) == t_end
        for name in FIGURES:
            # the figure from the sweep and from its own table: rounding (atol: zero figures)
            np.testing.assert_allclose(float(cells[name]), expected[name], rtol=1e-12, atol=1e-300, err_msg=name)


@pytest.mark.parametrize("backend", BACKENDS)
def test_grid_rows_are_the_product_and_match_their_own_solves(tmp_path, capsys, backend):
    status, out, err = sweep(tmp_path, capsys, "--grid", "L_rod=0.25:0.35:2", "--grid", "n=4:6:2",
                             "--backend", backend)
    assert status == 0, err
    header, rows = read_rows(tmp_path / "sweep.csv")
    assert [(r[1], r[2]) for r in rows] == [("0.25", "4"), ("0.25", "6"), ("0.34999999999999998", "4"),
                                            ("0.34999999999999998", "6")]  # the last grid fastest, 17 digits
    assert out.splitlines()[0] == f"{tmp_path / 'sweep.csv'}: 4 variants, 0 failed"
    assert_rows_match_solves(tmp_path, capsys, tmp_path / "sweep.csv", ["L_rod", "n"], backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_table_variants_match_their_own_solves(tmp_path, capsys, backend):
    (tmp_path / "v.csv").write_text("m_rod,L_crank\n1.3,0.09\n0.7,0.11\n", encoding="utf-8")
    status, _, err = sweep(tmp_path, capsys, "--table", str(tmp_path / "v.csv"), "--backend", backend)
    assert status == 0, err
    assert_rows_match_solves(tmp_path, capsys, tmp_path / "sweep.csv", ["m_rod", "L_crank"], backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_sample_is_seeded_and_matches_its_own_solves(tmp_path, capsys, backend):
    args = ("--sample", "3", "--normal", "L_rod=0.3,0.01", "--uniform", "m_slider=0.5,1.5", "--seed", "7")
    status, _, err = sweep(tmp_path, capsys, *args, "--backend", backend)
    assert status == 0, err
    _, rows = read_rows(tmp_path / "sweep.csv")
    rng = np.random.default_rng(7)
    drawn = np.column_stack([rng.normal(0.3, 0.01, 3), rng.uniform(0.5, 1.5, 3)])
    assert np.array_equal(np.array([r[1:3] for r in rows], dtype=float), drawn)
    assert_rows_match_solves(tmp_path, capsys, tmp_path / "sweep.csv", ["L_rod", "m_slider"], backend)


def test_a_failed_variant_keeps_its_row_and_the_figures_before(tmp_path, capsys):
    # a rod shorter than the crank cannot follow it: the run stops part way
    (tmp_path / "v.csv").write_text("L_rod\n0.3\n0.08\n", encoding="utf-8")
    status, out, err = sweep(tmp_path, capsys, "--table", str(tmp_path / "v.csv"))
    assert status == 0, err
    header, rows = read_rows(tmp_path / "sweep.csv")
    assert [r[header.index("status")] for r in rows] == ["ok", "not_converged"]
    assert "2 variants, 1 failed" in out
    expected, solved, t_end = truth(tmp_path, capsys, "c", {"L_rod": "0.08"})
    assert solved == "failed" and 0 < t_end < 0.2
    cells = dict(zip(header, rows[1]))
    assert float(cells["t_end"]) == t_end
    # the figure from the sweep and from its own table: rounding
    np.testing.assert_allclose(float(cells["motor.effort_peak"]), expected["motor.effort_peak"], rtol=1e-12)


def test_no_variant_solved_is_exit_3_with_the_table_written(tmp_path, capsys):
    status, _, err = sweep(tmp_path, capsys, "--grid", "L_rod=0.06:0.08:2")
    assert status == 3
    assert err.count("\n") == 1 and "no variant could be solved" in err
    _, rows = read_rows(tmp_path / "sweep.csv")
    assert len(rows) == 2 and all(r[3] != "ok" for r in rows)


def test_default_output_is_name_sweep_csv_and_json_has_the_figures(tmp_path, capsys, monkeypatch):
    import json

    monkeypatch.chdir(tmp_path)
    status = main(["sweep", CRANK, "--steps", STEPS, "--grid", "n=4:5:2", "--json"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    report = json.loads(captured.out)
    assert report["variants"] == 2 and report["failed"] == 0
    assert report["instants"] == 2 * int(STEPS)
    assert report["setup_s"] > 0 and report["solve_s"] > 0
    assert report["instants_per_s"] == pytest.approx(report["instants"] / report["solve_s"])
    assert (tmp_path / "slider_crank_sweep.csv").is_file()


def test_parquet_round_trip_is_the_csv_table(tmp_path, capsys):
    args = ("--sample", "4", "--normal", "m_rod=1,0.1", "--seed", "3")
    assert sweep(tmp_path, capsys, *args)[0] == 0
    assert sweep(tmp_path, capsys, *args, out="sweep.parquet")[0] == 0
    a, b = sweep_table.read(tmp_path / "sweep.csv"), sweep_table.read(tmp_path / "sweep.parquet")
    assert a.columns == b.columns and b.kind == "sample"
    assert np.array_equal(a.data, b.data, equal_nan=True)
    assert list(b["status"]) == ["ok"] * 4
    import pyarrow.parquet as pq

    schema = pq.read_schema(tmp_path / "sweep.parquet")
    assert str(schema.field("variant").type) == "int64" and str(schema.field("status").type) == "string"


def test_api_sweep_equals_the_command_line(tmp_path, capsys):
    assert sweep(tmp_path, capsys, "--grid", "n=4:6:3")[0] == 0
    table = api.sweep(api.load_mechanism(CRANK, steps=int(STEPS)), {"n": [4.0, 5.0, 6.0]})
    assert table.columns == read_rows(tmp_path / "sweep.csv")[0]
    assert np.array_equal(table.data, sweep_table.read(tmp_path / "sweep.csv").data)
    table.write(tmp_path / "api.csv")
    assert (tmp_path / "api.csv").read_text() == (tmp_path / "sweep.csv").read_text()


def test_grid_product_order_last_fastest():
    v = vary.grid(["a=0:1:2", "b=10:30:3"])
    assert v.names == ("a", "b")
    assert v.values.tolist() == [[0, 10], [0, 20], [0, 30], [1, 10], [1, 20], [1, 30]]


# -- Ctrl-C --------------------------------------------------------------------------

# slow: a sweep child run until the signal lands; tests/io/test_signals.py keeps a signal mid-run in the quick
# tier
@pytest.mark.slow
def test_sigint_mid_sweep_writes_the_finished_variants_and_exits_130(tmp_path):
    """The progress bar (stderr on a terminal) says when the variants run; then SIGINT.
    10^6 variants x 201 instants: over ten seconds on the batch engine (6e4
    variants/s), so the signal, sent once the bar shows, lands mid-sweep even
    when the machine is slow to deliver it (160000 once finished first)."""
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    out = tmp_path / "part.csv"
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "symid", "sweep", CRANK, "--steps", "201",
                             "--grid", "L_rod=0.25:0.35:1000", "--grid", "n=4:6:1000", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL, env=env, cwd=tmp_path,
                            preexec_fn=default_signals)  # a suite run as a background job ignores SIGINT
    os.close(slave)
    seen = b""
    deadline = time.monotonic() + 120
    try:
        while b"variants/s" not in seen and time.monotonic() < deadline and proc.poll() is None:
            if select.select([master], [], [], 0.5)[0]:
                try:
                    seen += os.read(master, 4096)
                except OSError:  # the child closed the terminal: it ended
                    break
        assert b"variants/s" in seen, (proc.poll(), seen)
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
        while select.select([master], [], [], 0.2)[0]:
            try:
                seen += os.read(master, 4096)
            except OSError:
                break
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    assert proc.returncode == 130, seen
    assert b"Traceback" not in seen
    header, rows = read_rows(out)
    assert 0 < len(rows) < 1_000_000
    # one line says it, after the progress bar's last redraw
    said = seen.decode().replace("\r", "\n").strip().splitlines()[-1]
    assert said == f"symid: interrupted; {out} holds the {len(rows)} variants finished before it", seen
    assert [r[0] for r in rows] == [str(k) for k in range(len(rows))]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left
    grid = vary.grid(["L_rod=0.25:0.35:1000", "n=4:6:1000"])
    first = api.sweep(api.load_mechanism(CRANK, steps=201), {"L_rod": grid.values[:2, 0], "n": grid.values[:2, 1]})
    assert np.array_equal(np.array([r[5:-1] for r in rows[:2]], dtype=float), first.figures.values)  # cond_worst last


def test_status_names_why_a_run_stopped():
    from symid.errors import AnalysisError
    from symid.study.figures import STATUS
    from symid.study.figures import status_of

    cases = {"Phi_q is singular (condition estimate 1e17); dependent constraints: a": "singular",
             "assembly mode jump: Newton moved q by 2 (scaled)": "jump",
             "qddot not finite (inf or NaN); in force f": "nonfinite",
             "Newton did not converge: Phi is not finite at the guess; in: a": "not_converged",
             "Newton did not converge in 50 iterations": "not_converged"}
    for message, status in cases.items():
        assert STATUS[status_of(AnalysisError(message, 0.1))] == status, message


def test_to_pandas_is_the_table_or_says_what_it_needs():
    table = api.sweep(api.load_mechanism(CRANK, steps=3), {"n": [4.0, 5.0]}, backend="numpy")
    try:
        import pandas  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="needs pandas"):
            table.to_pandas()
        return
    frame = table.to_pandas()
    assert list(frame.columns) == table.columns and list(frame["status"]) == ["ok", "ok"]
    assert frame["motor.effort_peak"].tolist() == table["motor.effort_peak"].tolist()
