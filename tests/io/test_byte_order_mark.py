"""A byte-order mark before an input's text (spreadsheets write one before CSV)
is dropped, never read as part of the first name: the variants table gave
the parameter '\\ufeffn' (issue 32). Each input read as text is tried with
and without one, and must give the same bytes out.
"""

from __future__ import annotations

from pathlib import Path

from symid import api
from symid.cli import main
from symid.cli.plot import read_results

CRANK = Path(api.example("slider_crank"))
BOM = "\ufeff"


def test_a_variants_table_with_a_bom_runs_as_without(tmp_path: Path, capsys) -> None:
    text = "n,L_rod\n4,0.3\n5,0.32\n"
    outs = []
    for name, prefix in (("plain", ""), ("bom", BOM)):
        table = tmp_path / f"{name}.csv"
        table.write_text(prefix + text, encoding="utf-8")
        out = tmp_path / f"{name}_out.csv"
        status = main(["sweep", str(CRANK), "--table", str(table), "--steps", "5", "--backend", "numpy",
                       "--workers", "1", "-o", str(out)])
        assert status == 0, capsys.readouterr().err
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert outs[1].decode().startswith("variant,n,L_rod,")


def test_a_mechanism_file_with_a_bom_solves_as_without(tmp_path: Path, capsys) -> None:
    bom = tmp_path / "crank.toml"
    bom.write_text(BOM + CRANK.read_text(encoding="utf-8"), encoding="utf-8")
    assert bom.read_bytes().startswith(b"\xef\xbb\xbf")
    for path, out in ((CRANK, tmp_path / "plain.csv"), (bom, tmp_path / "bom.csv")):
        assert main(["solve", str(path), "--steps", "5", "--backend", "reference", "-o", str(out)]) == 0
    assert (tmp_path / "plain.csv").read_bytes() == (tmp_path / "bom.csv").read_bytes()


def test_a_results_table_saved_with_a_bom_reads_with_t_first(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.csv"
    assert main(["solve", str(CRANK), "--steps", "5", "--backend", "reference", "-o", str(out)]) == 0
    saved = tmp_path / "saved.csv"
    saved.write_bytes(b"\xef\xbb\xbf" + out.read_bytes())  # as a spreadsheet saves "CSV UTF-8"
    plain, marked = read_results(out), read_results(saved)
    assert marked.columns == plain.columns and marked.columns[0] == "t"
    assert (marked.data == plain.data).all()


def test_a_bom_inside_the_text_is_not_dropped(tmp_path: Path, capsys) -> None:
    """Only a leading mark is an encoding mark: one in a name is still refused, named."""
    table = tmp_path / "v.csv"
    table.write_text("n,L" + BOM + "_rod\n4,0.3\n", encoding="utf-8")
    status = main(["sweep", str(CRANK), "--table", str(table), "--steps", "5", "-o", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert status == 2 and "no parameter 'L\\ufeff_rod'" in err, err
