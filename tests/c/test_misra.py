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
10.5)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

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
CHECK = ["--addon=misra", "--std=c99", "-q", "--max-configs=1"]
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


def findings(source: Path) -> list[tuple[str, str]]:
    """(rule, file:line) of every MISRA finding in the source and its header."""
    assert CPPCHECK is not None
    out = subprocess.run([CPPCHECK, *CHECK, source.name], cwd=source.parent, capture_output=True, text=True,
                         timeout=600)
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
