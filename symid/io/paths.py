"""The files a mechanism file refers to, found without reading it through sympy.

A tabled function (`f = { table = "motion.csv", column = ... }`, see
`symid.io.table`) names a CSV file relative to the mechanism file. The
reader and the run-plan cache (`symid.tools.plan`) resolve it by the one rule here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def table_path(name: str, source: str) -> Path:
    """Where table `name` of the mechanism file `source` is ("<string>": the current folder)."""
    return Path(name) if Path(name).is_absolute() else Path(source).parent / name


def referenced_tables(document: Any, source: str) -> list[Path]:
    """Every table a parsed mechanism file may read, in file order.

    Any inline table with a string `table` key counts, wherever it is: a
    superset of what the reader opens, so a change to any of them is seen.
    """
    found: list[Path] = []

    def walk(value: Any) -> None:
        if isinstance(value, dict):
            if isinstance(value.get("table"), str):
                found.append(table_path(value["table"], source))
            for item in value.values():
                walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)

    walk(document)
    return found
