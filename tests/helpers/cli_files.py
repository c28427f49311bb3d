"""The bundled slider-crank's text and its edits, and a CSV table read back."""

from __future__ import annotations

import csv
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "symid" / "examples"
SLIDER_CRANK = EXAMPLES / "slider_crank.toml"

def base_text() -> str:
    return SLIDER_CRANK.read_text(encoding="utf-8")


def set_line(text: str, key: str, value: str) -> str:
    """Set `key = ...` (a line of its own, once in the file) to `value`, keeping comments."""
    pattern = re.compile(rf"^{re.escape(key)}\s*=\s*[^#\n]*", re.M)
    assert len(pattern.findall(text)) == 1, f"{key} is not set exactly once"
    return pattern.sub(f"{key} = {value} ", text)


def with_analysis(text: str, lines: str) -> str:
    assert text.count("[analysis]\n") == 1
    return text.replace("[analysis]\n", "[analysis]\n" + lines + "\n")


def read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]
