"""`symid sweep --gradients`: d(FIGURE)/d(P) columns after the figures, each
equal to the gradient of that variant solved alone, and the figures equal to
the plain sweep's."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from symid import api
from symid.cli import main
from symid.study.figures import figure_names
from symid.study.gradients import figure_gradients, gradient_names, needed_columns
from symid.study.slow import study_analysis, with_values
from symid.output.results import columns
from symid.symbolic.assemble import assemble
from symid.tools.sensitive import solver

CRANK = str(api.example("slider_crank"))


def read(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and numbers of a sweep table (the status column, words, read as 0)."""
    rows = list(csv.reader(path.read_text().splitlines()))
    return rows[0], np.array([[_number(c) for c in r] for r in rows[1:]])


def _number(cell: str) -> float:
    try:
        return float(cell)
    except ValueError:  # "ok", "not_converged", ...
        return 0.0


def test_gradient_columns_follow_the_figures_and_match_each_variant(tmp_path):
    out = tmp_path / "g.csv"
    plain = tmp_path / "p.csv"
    grid = ["--grid", "L_rod=0.25:0.35:2", "--grid", "m_slider=0.8:1.2:2"]
    assert main(["sweep", CRANK, "--steps", "11", "--backend", "numpy", "--gradients", "-o", str(out), *grid]) == 0
    assert main(["sweep", CRANK, "--steps", "11", "--backend", "numpy", "-o", str(plain), *grid]) == 0
    header, data = read(out)
    plain_header, plain_data = read(plain)
    mech = study_analysis(api.load_mechanism(CRANK, steps=11))
    figures = list(figure_names(mech))
    names = ["L_rod", "m_slider"]
    assert header == plain_header[:-1] + gradient_names(figures, names) + ["cond_worst"]  # cond_worst last
    nfig = len(plain_header) - 1
    # the figures with and without gradients: the same solve, rounding
    np.testing.assert_allclose(data[:, :nfig], plain_data[:, :nfig], rtol=1e-10, atol=1e-12)
    assert np.array_equal(data[:, -1], plain_data[:, -1])  # no warning: 0
    solve = solver("numpy")
    for row in data:
        variant = with_values(mech, names, row[1:3])
        results = solve(variant, names, needed_columns(variant, columns(assemble(variant), variant.analysis)))
        expected = figure_gradients(variant, results, names).ravel()
        # the gradient from the sweep and from the variant solved alone: rounding of a tol 1e-12 solve
        np.testing.assert_allclose(row[nfig:-1], expected, rtol=1e-9, atol=1e-12)
    assert np.isnan(data[:, header.index("d(motor.effort_t_peak)/d(L_rod)")]).all()  # an instant: no gradient


def test_gradients_with_a_scheduler_is_refused(tmp_path, capsys):
    status = main(["sweep", CRANK, "--grid", "n=4:5:2", "--gradients", "--scheduler", "tcp://127.0.0.1:1",
                   "-o", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1
    assert "--gradients runs each variant on this machine" in err


def test_a_variant_that_fails_keeps_its_row_with_the_gradients_of_the_instants_before(tmp_path):
    """A rod shorter than the crank cannot follow it: that variant's status says
    so, the other variant's row is whole, and the sweep goes on (exit 0)."""
    out = tmp_path / "g.csv"
    assert main(["sweep", CRANK, "--steps", "11", "--backend", "numpy", "--gradients", "-o", str(out),
                 "--table", str(_variants(tmp_path))]) == 0
    lines = out.read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    status = header.index("status")
    assert rows[0][status] == "ok" and rows[1][status] in ("not_converged", "singular", "jump")
    grad = header.index("d(motor.effort_rms)/d(L_rod)")
    assert np.isfinite(float(rows[0][grad]))


def _variants(tmp_path: Path) -> Path:
    path = tmp_path / "variants.csv"
    path.write_text("L_rod\n0.3\n0.08\n")
    return path
