"""MISRA C:2012 on the generated C (issue #30, point 4): cppcheck's MISRA
addon on every bundled example's export finds nothing but the rules the
deviation record (docs/misra.md) keeps, and every rule the record keeps still
occurs (so the record stays true). The record's suppressions block is what a
user passes to cppcheck to rerun the check on their own export.

What each check costs is cppcheck's addon (seconds an export), so each export
checked holds distinct code: per example, single precision with
sensitivities (the float literals and libm names, the phases' float-float
code, the sensitivities, and for the friction example friction's solve and
its sensitivities: everything a plain double export has but the double
literals, which print the same expressions); and the excavator's plain double
export, which holds every rule the record keeps (its sign() is the one
10.5).

The addon is the installed one with rule 8.2's raw-token search indexed
(tests/helpers/misra_addon.py: 40 % of its time on an export, the same
findings; test_indexed_addon_reports_what_the_stock_addon_reports), run
without Python's cyclic garbage collector and by the tests' interpreter
(15 % of what is left, the same findings byte for byte)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import misra_addon
from cbuild import example_export
from symid import api

CPPCHECK = shutil.which("cppcheck")
pytestmark = pytest.mark.skipif(CPPCHECK is None, reason="cppcheck is not installed (the MISRA check needs its addon)")

RECORD = Path(__file__).resolve().parents[2] / "docs" / "misra.md"
FINDING = re.compile(r"^(?P<where>[^\s:]+:\d+):\d+: .*\[misra-c2012-(?P<rule>[\d.]+)\]$", re.M)
# --max-configs=1: cppcheck checks each combination of the #ifdefs it sees
# (__GNUC__, <P>_REAL, ...), and the generated code's differ only in what a
# macro expands to (the cold attribute, the real typedef), never in which
# statements are compiled: the first configuration holds every statement, at
# half the time of all of them (the findings are the same, counted per rule).
# Without the record's --enable=style: the addon reads cppcheck's dump, which
# is the same whatever cppcheck's own checks are, and style's checks are a
# third of the time for findings this test does not read (the excavator's
# single export with sensitivities: the same 100 MISRA findings either way).
CHECK = ["--std=c99", "-q", "--max-configs=1"]
# the exports that together hold every kept rule (test_record_rules_each_still_occur)
RECORD_EXPORTS = (("excavator", "double"),)


def kept() -> set[str]:
    """The rules the record keeps: the lines misra-c2012-R.N of its suppressions block."""
    return set(re.findall(r"^misra-c2012-([\d.]+)$", RECORD.read_text(), re.M))


def export(name: str, variant: str, folder: Path, factory: pytest.TempPathFactory | None = None) -> Path:
    """The example's C export: "double" (the run's shared one, copied into
    folder: cppcheck writes its dump beside the source), or "single-sens"
    (single precision, sensitivities to its first base parameter: one
    parameter's code is each parameter's, and the derivation costs per
    parameter)."""
    if variant == "double":
        assert factory is not None
        source = example_export(factory, name).source("double")
        folder.mkdir(parents=True)
        for path in (source, source.with_suffix(".h")):
            shutil.copy(path, folder / path.name)
    else:
        first = next(iter(api.load_mechanism(api.example(name)).parameters))
        api.generate(api.example(name), "c", folder, precision="single", sensitivity=(first,))
    return next(folder.glob("*_solver.c"))


def findings(source: Path, addon: str | None = None) -> list[tuple[str, str]]:
    """(rule, file:line) of every MISRA finding in the source and its header
    (addon: cppcheck's --addon option, else the indexed addon's)."""
    assert CPPCHECK is not None
    out = subprocess.run([CPPCHECK, addon or misra_addon.addon_option(source.parent), *CHECK, source.name],
                         cwd=source.parent, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return [(m["rule"], m["where"]) for m in FINDING.finditer(out.stderr)]


def outside(found: list[tuple[str, str]]) -> list[str]:
    return [f"{where}: rule {rule}" for rule, where in found if rule not in kept()]


def test_record_keeps_rules_with_a_reason_each() -> None:
    """Each suppressed rule has its entry (a '### Rule R.N' heading) and the
    reverse; nothing is left pending."""
    text = RECORD.read_text()
    entries = set(re.findall(r"^### Rule ([\d.]+) ", text, re.M))
    assert entries == kept() and kept()
    assert not re.search(r"^pending misra-c2012-", text, re.M)


@pytest.mark.slow  # cppcheck's MISRA addon over the excavator's exports (seconds)
def test_record_rules_each_still_occur_and_nothing_else(tmp_path_factory, tmp_path: Path) -> None:
    """The fixed set of exports holds every rule the record keeps (a rule
    fixed away must leave the record) and no other."""
    seen: set[str] = set()
    for name, variant in RECORD_EXPORTS:
        found = findings(export(name, variant, tmp_path / f"{name}-{variant}", tmp_path_factory))
        assert not outside(found), (name, variant, outside(found)[:20])
        seen |= {rule for rule, _ in found}
    stale = kept() - seen
    assert not stale, f"the record keeps rules that no longer occur: {sorted(stale)}"


@pytest.mark.slow  # cppcheck's addon and the sensitivities' derivation: 4 to 20 s an example
@pytest.mark.parametrize("example", api.examples())
def test_every_example_export_has_no_finding_outside_the_record(tmp_path: Path, example: str) -> None:
    found = findings(export(example, "single-sens", tmp_path))
    assert not outside(found), outside(found)[:30]


# rule 8.2 on pointer declarations: a function pointer's parameter list read
# through comments (line 5), an unnamed one's empty list (4, 11, the
# parameter g on 9), a prototype without (void) (14); 3, 7 and f comply
SMALL = """\
/* rule 8.2 reads every pointer declaration's next raw tokens */
static int twice(int x) { return 2 * x; }
static int (*named)(int) = twice;
static int (*unnamed)() = 0;
static int (*commented /* a comment */)( /* another */ ) = 0;
// a line comment
static int (*last)(void) = 0;
int use(const int *p, int *q, int (*f)(int), int (*g)());
int use(const int *p, int *q, int (*f)(int), int (*g)()) {
    int *r = q;
    int (*h)() = g;
    return f(*p) + *r + h() + named(1) + (unnamed != 0) + (commented != 0) + (last != 0);
}
void none();
"""


@pytest.mark.slow  # two cppcheck runs with the addon on a 14-line file (a second)
def test_indexed_addon_reports_what_the_stock_addon_reports(tmp_path: Path) -> None:
    """The indexed addon swaps rule 8.2's search in the installed misra.py
    (not the stock addon run under another name), and on pointer
    declarations of every kind 8.2 reads it reports, as the stock addon,
    every finding of every rule, 8.2 on the lines read by hand."""
    stock = misra_addon.stock_addon()
    assert stock is not None, "cppcheck is installed but its misra.py is not where misra_addon looks"
    helpers = Path(misra_addon.__file__).parent
    swapped = subprocess.run([sys.executable, "-c", f"import sys; sys.path[:0] = [{str(stock.parent)!r}, "
                              f"{str(helpers)!r}]; import misra, misra_addon; print(misra_addon._indexed(misra))"],
                             capture_output=True, text=True, check=True).stdout.split()
    assert swapped == ["True"]
    source = tmp_path / "small.c"
    source.write_text(SMALL)
    indexed = sorted(findings(source))
    assert indexed == sorted(findings(source, "--addon=misra"))
    assert {where for rule, where in indexed if rule == "8.2"} == {f"small.c:{n}" for n in (4, 5, 9, 11, 14)}
