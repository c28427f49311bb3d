"""Code-generation targets behind one registry: c, numpy, casadi, fmu.

A target is a module with `NAME` and `generate(model, out_dir) -> list[Path]`;
the C target is the package `symid.codegen.c`.
"""

from __future__ import annotations

from importlib import import_module
from types import ModuleType

from symid.errors import InputError

TARGETS = {"c": "symid.codegen.c", "numpy": "symid.codegen.targets.numpy_target",
           "casadi": "symid.codegen.targets.casadi_target", "fmu": "symid.codegen.fmu"}


def get(name: str) -> ModuleType:
    """The target module `name`; an input error lists the valid ones."""
    if name not in TARGETS:
        raise InputError(f"--target: unknown target {name!r} (valid: {', '.join(TARGETS)})")
    return import_module(TARGETS[name])
