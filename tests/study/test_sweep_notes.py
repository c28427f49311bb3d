"""A sweep says which variants were badly conditioned, as their own solves
warn: the table's last column `cond_worst` (the worst condition estimate of
Phi_q past cond_warn, 0 without a warning) and one line on stderr naming
them. A scissor lift driven by its foot until its arms are e from flat
(radians): the condition number grows like 1 / e, so e = 1e-7 is past
cond_warn = 1e6 (9e7, tests/backends/test_singular_screen.py) and 0.05, 0.1
are far below it."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main
from symid.study import table as sweep_table
from scissor import scissor_lift

SCISSOR = scissor_lift("scissor_notes", """
L = 1.0
a0 = 0.6
e = 0.05
m_arm = 5.0
m_top = 50.0
""", 41, "a0 + e", "pi - a0 - e", "L*cos(a0*(1 - t) + e)", "m_arm", "m_top")
VALUES = ("0.05", "1e-7", "0.1")  # variant 1 near the singular position at t1


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


# slow: a sweep over ill-conditioned variants on two backends; the sweep notes' other tests stay in the quick
# tier
@pytest.mark.slow
@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_a_sweep_names_its_ill_conditioned_variants_as_their_solves_warn(tmp_path: Path, capsys,
                                                                          backend: str) -> None:
    mech = tmp_path / "scissor_notes.toml"
    mech.write_text(SCISSOR)
    variants = tmp_path / "v.csv"
    variants.write_text("e\n" + "\n".join(VALUES) + "\n")
    out = tmp_path / "sweep.csv"
    assert main(["sweep", str(mech), "--table", str(variants), "--backend", backend, "-o", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    header, rows = _rows(out)
    assert header[-1] == "cond_worst"
    cond = [float(r[-1]) for r in rows]
    assert cond[0] == 0.0 and cond[2] == 0.0 and cond[1] > 1e6
    assert [r[header.index("status")] for r in rows] == ["ok"] * 3
    # the variant's own solve warns with the same worst condition estimate (its 3 digits)
    assert main(["solve", str(mech), "--set", "e=1e-7", "--backend", backend, "-o", str(tmp_path / "s.csv")]) == 0
    solved = [line for line in capsys.readouterr().err.splitlines() if "ill-conditioned" in line]
    assert len(solved) == 1 and re.search(r"worst ([^ ]+) at", solved[0])[1] == f"{cond[1]:.3g}", solved
    warned = [line for line in err if "ill-conditioned" in line]
    assert len(warned) == 1 and warned[0].startswith("symid: warning: "), err
    assert "in 1 of 3 variants: 1 (worst" in warned[0] and f"{cond[1]:.3g}" in warned[0] and "cond_worst" in warned[0]
    # read back (symid plot reads it so): cond_worst is not a figure
    back = sweep_table.read(out)
    assert "cond_worst" not in back.figures.names and list(back.figures.cond) == cond


def test_no_warning_and_zeros_where_every_variant_is_well_conditioned(tmp_path: Path, capsys) -> None:
    mech = tmp_path / "scissor_notes.toml"
    mech.write_text(SCISSOR)
    out = tmp_path / "sweep.parquet"
    assert main(["sweep", str(mech), "--grid", "e=0.05:0.1:3", "--backend", "numpy", "-o", str(out)]) == 0
    assert "warning" not in capsys.readouterr().err
    back = sweep_table.read(out)
    assert back.columns[-1] == "cond_worst" and np.array_equal(back["cond_worst"], np.zeros(3))


def test_the_api_table_and_a_study_on_the_python_loop_carry_the_notes(tmp_path: Path) -> None:
    """`api.sweep` on reference (each variant through the normal path) keeps the column too."""
    mech = tmp_path / "scissor_notes.toml"
    mech.write_text(SCISSOR)
    table = api.sweep(mech, {"e": [float(v) for v in VALUES]}, backend="reference")
    cond = table["cond_worst"]
    assert cond[0] == 0.0 and cond[2] == 0.0 and cond[1] > 1e6
    assert list(table.figures.warned) == [1]
