"""The bundled studies of docs/studies.md (`symid help studies`) say what their own commands give: the
slider-crank grid's peak and RMS motor torque at its corners, and the
tolerance study's nominal peak, P50, P95, P99 and largest peak. The
commands are read from the page and run as written (without --plot)."""

from __future__ import annotations

import csv
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main

README = (Path(__file__).resolve().parents[2] / "docs" / "studies.md").read_text(encoding="utf-8")
CRANK = str(api.example("slider_crank"))


def command(marker: str) -> list[str]:
    """The page's indented `symid sweep` command whose text holds marker, as argv."""
    for block in re.findall(r"\n    (symid sweep .*?)\n\n", README, re.S):
        if marker in block:
            words = shlex.split(block.replace("\\\n", " ").replace('"$(symid example slider_crank)"', CRANK))
            return [w for w in words[1:] if w != "--plot"]
    raise AssertionError(f"no sweep command with {marker} in docs/studies.md")


def run(tmp_path: Path, argv: list[str]) -> dict[str, np.ndarray]:
    out = tmp_path / "study.csv"
    k = argv.index("-o")
    assert main([*argv[:k], "-o", str(out), *argv[k + 2:]]) == 0
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert all(r["status"] == "ok" for r in rows)
    return {key: np.array([float(r[key]) for r in rows]) for key in rows[0] if key != "status"}


def said(text: str) -> float:
    """The number the page writes right after text."""
    m = re.search(re.escape(text) + r"\s*([0-9.]+)", README)
    assert m, text
    return float(m.group(1))


def test_the_grid_study_figures_are_what_its_command_gives(tmp_path: Path) -> None:
    t = run(tmp_path, command("--grid L_rod="))
    def at(L: float, n: float, key: str) -> float:
        (k,) = np.flatnonzero(np.isclose(t["L_rod"], L) & np.isclose(t["n"], n))
        return float(t[key][k])
    assert round(at(0.2, 5, "motor.effort_peak"), 1) == said("and falls with a longer\nrod:")
    assert round(at(0.2, 5, "motor.effort_rms"), 1) == said("rod: 17.6 N·m (RMS")
    assert round(at(0.4, 5, "motor.effort_peak"), 1) == said("at L_rod = 0.2 m, n = 5 against")
    assert round(at(0.2, 10, "motor.effort_peak"), 1) == said("0.4 m; at n = 10,")
    assert round(at(0.4, 10, "motor.effort_peak"), 1) == said("N·m (RMS 26.8) against")


def test_the_tolerance_study_percentiles_are_what_its_command_gives(tmp_path: Path) -> None:
    t = run(tmp_path, command("--sample 1000 --seed 1"))
    peak = t["motor.effort_peak"]
    nominal = api.solve(api.load_mechanism(CRANK), backend="c")
    assert round(float(np.max(np.abs(nominal["motor.T_j"]))), 2) == said("The nominal design's peak motor torque is")
    assert round(float(np.percentile(peak, 50)), 2) == said("over the sample, P50")
    assert round(float(np.percentile(peak, 95)), 2) == said(", P95")
    assert round(float(np.percentile(peak, 99)), 2) == pytest.approx(said("**P99"))
    assert round(float(peak.max()), 2) == said("(largest")
