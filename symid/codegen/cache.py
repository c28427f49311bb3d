"""Where generated solvers are kept between runs, keyed by what they depend on.

The key hashes the mechanism's structure (parameter values excluded: they
are run-time inputs), the generation options and symid's own code and
templates, so a change to any of them regenerates and nothing stale is used.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from symid.sources import code_version

if TYPE_CHECKING:  # a cached run (symid.plan) finds its solver here without sympy
    from symid.codegen.flat import Options
    from symid.model import Mechanism


def cache_root() -> Path:
    """$SYMID_CACHE, else $XDG_CACHE_HOME/symid, else ~/.cache/symid."""
    if "SYMID_CACHE" in os.environ:
        return Path(os.environ["SYMID_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "symid"


def key(mech: Mechanism, options: Options, target: str) -> str:
    """The cache key of one generated solver."""
    structure = dataclasses.replace(mech, parameters={n: None for n in mech.parameters}, source="",
                                    analysis=None)  # type: ignore[arg-type]
    text = repr((structure, options, target, code_version()))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def cached(mech: Mechanism, options: Options, target: str, make: Callable[[Path], None]) -> Path:
    """The cache folder of one generated artefact, made by `make(folder)` if absent.

    `make` writes into a private staging folder that is renamed into place
    only when complete, so concurrent runs and failures never leave a
    half-built entry.
    """
    folder = cache_root() / f"{target}-{mech.name}-{key(mech, options, target)}"
    if (folder / "complete").is_file():
        return folder
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=folder.name + ".", dir=folder.parent))
    try:
        make(staging)
        (staging / "complete").write_text("")
        try:
            staging.rename(folder)
        except OSError:  # built meanwhile by another process, or a stale partial folder
            if not (folder / "complete").is_file():
                shutil.rmtree(folder, ignore_errors=True)
                staging.rename(folder)
            else:
                shutil.rmtree(staging, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return folder
