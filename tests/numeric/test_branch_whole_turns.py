"""The branch check's whole-turns answer (symid.numeric.solve._branch returns
the position with some angles a whole turn on) was combined with `or`, which
an array refuses: a slider-crank whose rod is the crank's length to 1e-8
ended `symid solve` in a ValueError traceback instead of the analysis's own
"singular position" exit 3."""

from __future__ import annotations

from symid import api
from symid.cli import main
from symid.errors import AnalysisError


def test_a_rod_as_long_as_the_crank_ends_in_the_analysis_error_not_a_traceback(tmp_path, capsys) -> None:
    path = api.example("slider_crank")
    res = api.prepare(path, "numpy", set_values={"L_rod": "1.00000001e-1"}, steps=201).solve()
    assert isinstance(res.error, AnalysisError) and "singular position" in str(res.error)
    status = main(["solve", str(path), "--set", "L_rod=1.00000001e-1", "--steps", "201", "-o", str(tmp_path / "s.csv")])
    err = capsys.readouterr().err.splitlines()
    assert status == 3 and len(err) == 1 and "singular position" in err[0], err
