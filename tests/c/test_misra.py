"""MISRA C:2012 on the generated C (issue #30, point 4): cppcheck's MISRA
addon on every bundled example's export, in both precisions and with
sensitivities, finds nothing but the rules the deviation record
(docs/misra.md) keeps, and every rule the record keeps still occurs (so the
record stays true). The record's suppressions block is what a user passes
to cppcheck to rerun the check on their own export."""

from __future__ import annotations

import re
import shutil
import subprocess
from collections import Counter
from pathlib import Path

import pytest

from symid import api

CPPCHECK = shutil.which("cppcheck")
pytestmark = pytest.mark.skipif(CPPCHECK is None, reason="cppcheck is not installed (the MISRA check needs its addon)")

RECORD = Path(__file__).resolve().parents[2] / "docs" / "misra.md"
FINDING = re.compile(r"^(?P<where>[^\s:]+:\d+):\d+: .*\[misra-c2012-(?P<rule>[\d.]+)\]$", re.M)
# the exports checked: both precisions, each with and without sensitivities
VARIANTS = {"double": {}, "single": {"precision": "single"}, "sens": {"sensitivity": 2},
            "single-sens": {"precision": "single", "sensitivity": 2}}


def kept() -> set[str]:
    """The rules the record keeps: the lines misra-c2012-R.N of its suppressions block."""
    return set(re.findall(r"^misra-c2012-([\d.]+)$", RECORD.read_text(), re.M))


def pending() -> set[str]:
    """The rules the record lists as not yet fixed in the code only some exports
    hold (sensitivities, joint friction, single precision's phase)."""
    return set(re.findall(r"^pending misra-c2012-([\d.]+)$", RECORD.read_text(), re.M))


def allowed(name: str, variant: str) -> set[str]:
    """A double export without sensitivities nor friction: the kept rules only."""
    plain = variant == "double" and "friction" not in name
    return kept() if plain else kept() | pending()


def export(name: str, variant: str, folder: Path) -> Path:
    """The example's C export in the variant (sensitivities: to its first two parameters)."""
    kw = dict(VARIANTS[variant])
    if "sensitivity" in kw:
        kw["sensitivity"] = tuple(list(api.load_mechanism(api.example(name)).parameters)[:kw["sensitivity"]])
    api.generate(api.example(name), "c", folder, **kw)  # type: ignore[arg-type]
    return next(folder.glob("*_solver.c"))


def findings(source: Path) -> list[tuple[str, str]]:
    """(rule, file:line) of every MISRA finding in the source and its header."""
    assert CPPCHECK is not None
    out = subprocess.run([CPPCHECK, "--addon=misra", "--std=c99", "-q", "--enable=style", source.name],
                         cwd=source.parent, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return [(m["rule"], m["where"]) for m in FINDING.finditer(out.stderr)]


def outside(found: list[tuple[str, str]], rules: set[str]) -> list[str]:
    return [f"{where}: rule {rule}" for rule, where in found if rule not in rules]


def test_record_keeps_rules_with_a_reason_each() -> None:
    """Each suppressed rule has its entry (a '### Rule R.N' heading) and the reverse."""
    text = RECORD.read_text()
    entries = set(re.findall(r"^### Rule ([\d.]+) ", text, re.M))
    assert entries == kept() and kept()
    assert not kept() & pending()


def test_slider_crank_export_has_no_finding_outside_the_record(tmp_path: Path) -> None:
    found = findings(export("slider_crank", "double", tmp_path))
    assert not outside(found, allowed("slider_crank", "double")), outside(found, kept())[:20]


@pytest.mark.slow
def test_every_example_export_has_no_finding_outside_the_record_and_each_entry_still_occurs(tmp_path: Path) -> None:
    seen: Counter[str] = Counter()
    bad: list[str] = []
    for name in api.examples():
        for variant in VARIANTS:
            found = findings(export(name, variant, tmp_path / f"{name}-{variant}"))
            seen.update(rule for rule, _ in found)
            bad += [f"{name} ({variant}) {line}" for line in outside(found, allowed(name, variant))]
    assert not bad, bad[:30]
    stale = (kept() | pending()) - set(seen)
    assert not stale, f"the record keeps rules that no longer occur: {sorted(stale)}"
