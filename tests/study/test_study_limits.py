"""A study's size is estimated and refused before any work: the variants'
count (`MAX_VARIANTS`) and the values it will hold in memory
(`MAX_HELD_VALUES`: its table of variants plus one variant's instants x
columns), each refused with one line naming the counts and the limit.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.io.limits import MAX_HELD_VALUES, MAX_VARIANTS
from symid.study import design
from symid.study.figures import figure_names
from symid.study.run import check_memory, held_values

CRANK = str(api.example("slider_crank"))


def _solve_width(tmp_path: Path) -> int:
    """The columns of a full solve of the slider-crank, read from a real run's CSV header
    (the table the normal path holds for one variant)."""
    out = tmp_path / "w.csv"
    assert main(["solve", CRANK, "--steps", "2", "-o", str(out)]) == 0
    with open(out, newline="") as f:
        return len(next(csv.reader(f)))


def test_held_values_counts_the_table_and_one_variants_instants(tmp_path: Path, capsys) -> None:
    width = _solve_width(tmp_path)
    capsys.readouterr()
    mech = api.load_mechanism(CRANK, steps=1001)
    variants = design.grid(["n=1:2:7", "L_rod=0.3:0.35:3"])
    figures = len(figure_names(mech))
    total, table = held_values(mech, variants, "c")
    assert table == 21 * (2 + figures + 2)  # 21 rows: 2 varied, the figures, status and t_end
    assert total == table + 1001 * width


def test_a_study_past_the_memory_limit_is_refused_before_work(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out.csv"
    status = main(["sweep", CRANK, "--grid", "n=1:2:2", "--steps", "10000000", "--backend", "numpy", "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "--grid: 2 variants of 10000000 instants: about" in err and f"the {MAX_HELD_VALUES} (1 GiB)" in err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_the_memory_limit_is_the_estimate_not_a_rougher_rule(tmp_path: Path) -> None:
    """Just under the limit passes, just over it is refused (the same study, one step apart)."""
    width = _solve_width(tmp_path)
    variants = design.grid(["n=1:2:2"])
    mech = api.load_mechanism(CRANK)
    _, table = held_values(mech, variants, "c")
    steps = (MAX_HELD_VALUES - table) // width
    check_memory(api.load_mechanism(CRANK, steps=steps), variants, "c", "x")
    with pytest.raises(api.InputError, match=f"x: 2 variants of {steps + 1} instants"):
        check_memory(api.load_mechanism(CRANK, steps=steps + 1), variants, "c", "x")


def test_gradients_count_their_sensitivity_columns() -> None:
    mech = api.load_mechanism(CRANK, steps=101)
    variants = design.grid(["n=1:2:2", "L_rod=0.3:0.35:2"])
    plain, plain_table = held_values(mech, variants, "c")
    grad, grad_table = held_values(mech, variants, "c", gradients=True)
    figures = len(figure_names(mech))
    assert grad_table - plain_table == 4 * figures * 2  # each figure's gradient by each of the 2 varied
    assert grad - grad_table == 3 * (plain - plain_table)  # each column and its 2 derivatives


def test_the_api_sweep_refuses_too_large_a_study_too(monkeypatch) -> None:
    import symid.io.limits

    monkeypatch.setattr(symid.io.limits, "MAX_HELD_VALUES", 1000)  # a small study past a small limit
    mech = api.load_mechanism(CRANK, steps=101)
    with pytest.raises(api.InputError, match="2 variants of 101 instants: about .* more than the 1000"):
        api.sweep(mech, {"n": [1.0, 2.0]}, backend="numpy")


def test_an_optimization_past_the_memory_limit_is_refused_before_work(tmp_path: Path, capsys) -> None:
    """Each point holds one variant's table with its sensitivities: 10^7 instants x 67 columns x 2."""
    out = tmp_path / "best.toml"
    status = main(["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "n=4:6", "--steps", "10000000",
                   "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert "--vary: 1 variant of 10000000 instants: about 13400000" in err and str(MAX_HELD_VALUES) in err, err
    assert not out.exists()


def test_a_grid_of_10_to_the_12_variants_names_the_count_and_the_limit(tmp_path: Path, capsys) -> None:
    status = main(["sweep", CRANK, "--grid", "n=1:2:1000000", "--grid", "L_rod=0.3:0.4:1000000",
                   "-o", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert f"1000000000000 variants, more than the {MAX_VARIANTS} a sweep allows" in err
