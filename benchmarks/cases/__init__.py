"""The benchmark's cases: each module here that calls `register` adds one.

A case is a function of a `benchmarks.run.Context` that measures and returns
a dict of figures; the harness (`python -m benchmarks CASE`) runs it, writes
the figures to `<out>/<case>.json` and prints them. Modules here that
register nothing are a case's helpers.

The registry is read from the `@register(...)` lines of the modules' source
(their literal arguments), without importing them: a module is imported when
its case runs or its options are asked for, so that `--list`, `--help` and
the harness's errors do not import symid, sympy and numpy for every case.
"""

from __future__ import annotations

import argparse
import ast
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


CASES: dict[str, Case] = {}  # the cases of the modules imported so far


def register(name: str, summary: str, **kw: Any) -> Callable[[Callable[[Context], dict[str, Any]]],
                                                                  Callable[[Context], dict[str, Any]]]:
    """Decorator: the function becomes the case `name` (keywords: see `Case`)."""
    def add(fn: Callable[[Context], dict[str, Any]]) -> Callable[[Context], dict[str, Any]]:
        if name in CASES:
            raise ValueError(f"two benchmark cases named {name}")
        CASES[name] = Case(name, fn, summary, **kw)
        return fn
    return add


def _imported(module: str, name: str) -> Case:
    importlib.import_module(module)
    return CASES[name]


def _deferred(module: str, name: str, attr: str) -> Callable[..., Any]:
    """The case's `attr` (run, options, report), its module imported at the first call."""
    def call(*args: Any) -> Any:
        return getattr(_imported(module, name), attr)(*args)
    return call


def _declared(module: str, path: Path) -> list[Case] | None:
    """The cases the module's `@register(...)` lines declare, or None if an argument is
    not a literal (a name or string the module computes: then it is imported)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        for deco in getattr(node, "decorator_list", []):
            if not (isinstance(deco, ast.Call) and isinstance(deco.func, ast.Name) and deco.func.id == "register"):
                continue
            try:
                name, summary = (ast.literal_eval(a) for a in deco.args)
                keys = {k.arg: k.value for k in deco.keywords}
                tools = tuple(ast.literal_eval(keys.pop("tools", ast.Constant(()))))
            except ValueError:
                return None
            if set(keys) - {"options", "report"}:
                return None
            found.append(Case(name, _deferred(module, name, "run"), summary, tools=tools,
                              **{k: _deferred(module, name, k) for k in keys}))
    return found


def load_all() -> dict[str, Case]:
    """Every case of this package's modules, by name (each module imported only when its
    case runs, unless its `@register` line is not literal)."""
    declared: dict[str, Case] = {}
    for info in pkgutil.iter_modules(__path__):
        module = f"{__name__}.{info.name}"
        cases = _declared(module, Path(__path__[0]) / f"{info.name}.py")
        if cases is None:
            importlib.import_module(module)
            cases = [c for c in CASES.values() if c.run.__module__ == module]
        for case in cases:
            if case.name in declared:
                raise ValueError(f"two benchmark cases named {case.name}")
            declared[case.name] = case
    return dict(sorted(declared.items()))
