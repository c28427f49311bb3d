"""The benchmark's cases: each module here that calls `register` adds one.

A case is a function of a `benchmarks.run.Context` that measures and returns
a dict of figures; the harness (`python -m benchmarks CASE`) runs it, writes
the figures to `<out>/<case>.json` and prints them. Modules here that
register nothing are a case's helpers.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

if TYPE_CHECKING:
    from benchmarks.run import Context


@dataclass(frozen=True)
class Case:
    """One registered case.

    Attributes:
        name: what `python -m benchmarks NAME` runs; its results are NAME.json.
        run: the measurement; returns the figures (JSON-able).
        summary: one line for `--list`.
        options: adds the case's own options to its parser.
        report: writes extra files beside the JSON (tables, plots) from the whole result (the JSON's
            dict: figures, machine, load averages); returns their paths.
        tools: programs the case cannot run without (gcc, valgrind, ...).
    """

    name: str
    run: Callable[[Context], dict[str, Any]]
    summary: str
    options: Callable[[argparse.ArgumentParser], None] | None = None
    report: Callable[[dict[str, Any], Path], list[Path]] | None = None
    tools: tuple[str, ...] = field(default_factory=tuple)


CASES: dict[str, Case] = {}


def register(name: str, summary: str, **kw: Any) -> Callable[[Callable[[Context], dict[str, Any]]],
                                                                  Callable[[Context], dict[str, Any]]]:
    """Decorator: the function becomes the case `name` (keywords: see `Case`)."""
    def add(fn: Callable[[Context], dict[str, Any]]) -> Callable[[Context], dict[str, Any]]:
        if name in CASES:
            raise ValueError(f"two benchmark cases named {name}")
        CASES[name] = Case(name, fn, summary, **kw)
        return fn
    return add


def load_all() -> dict[str, Case]:
    """Import every module of this package (each registers its cases); the registry by name."""
    for info in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{info.name}")
    return dict(sorted(CASES.items()))
