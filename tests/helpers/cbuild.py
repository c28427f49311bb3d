"""Building the generated C in the tests: the strict flags every build uses,
the embedded build's warnings and Cortex-M4F target, and the mark that skips
a test on a machine without a C compiler; the single-precision bounds and
the rows driver's run (tests/c/rows_driver.c).

What several tests build from the same text is built once per run and shared
by the workers (tests/helpers/runshare.py): each example's export in both
precisions (example_export), each small mechanism's (case_export), an object
compiled from a source with given flags (object_file: the Cortex-M4F objects
that the strict build, the double-helper link and the emulated run each
compiled, the host objects the rows driver, the double-promotion check and
the exports' strict libraries each compiled) and the host rows driver's run
of an example (host_rows). Each entry is keyed on the content it is made from and
on the command."""

from __future__ import annotations

import os
import pickle
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from runshare import key_of, shared_dir
from symid import api
from symid.cli import main
from symid.codegen import c as c_target
from symid.codegen.model import code_model
from symid.io.reader import load

STRICT = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic"]
# the embedded engineer's build (tests/c/test_c_embedded.py): conversions, promotions, shadowing
WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Wconversion", "-Wdouble-promotion", "-Wshadow"]
M4F = ["-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-mthumb"]
needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")


# single against double over each bundled run: max |diff| / the column's peak
# (a column below 1e-3 of its group's peak, zero but for rounding: against
# 1e-3 of that peak), within the bound the single-precision header states
# (single_bound); docs/c-export.md's own figure for the slider-crank is tighter
GROUP_FLOOR = 1e-3
DOC_FIGURES = {"slider_crank": 2e-6}


def single_bound(folder: Path, name: str) -> float:
    """The bound of single precision against double that the generated
    single-precision header in folder states (#define <NAME>_SINGLE_BOUND),
    tightened to docs/c-export.md's figure for the example where it states one."""
    header = (folder / f"{name}_solver.h").read_text()
    m = re.search(rf"^#define {name.upper()}_SINGLE_BOUND (\S+?)f?$", header, re.M)
    assert m is not None, f"{folder}: the single-precision header states no bound"
    return min(float(m.group(1)), DOC_FIGURES.get(name, 1.0))

DRIVER = Path(__file__).resolve().parents[1] / "c" / "rows_driver.c"


def driver_rows(exe: Path, t0: float, h: float, n: int, q0) -> np.ndarray:  # type: ignore[no-untyped-def]
    args = [str(exe), "rows", repr(t0), repr(h), str(n), *(repr(float(v)) for v in q0)]
    return np.loadtxt(subprocess.run(args, check=True, capture_output=True, text=True).stdout.splitlines(), ndmin=2)


# --- built once per run, shared by the tests and the workers ---

PRECISIONS = ("double", "single")
# the host build of a solver's object (the rows driver's, the double-promotion
# check's, the strict check's, an export's library): WARNINGS (-Wconversion
# holds -Wfloat-conversion, named for the single build's check) at -O2, so the
# optimizer's warnings run too, position-independent as the emitted Makefile
# builds it (one object links into a program and into a shared library)
HOST_O2 = ["cc", *WARNINGS, "-Wfloat-conversion", "-O2", "-fPIC"]


@dataclass(frozen=True)
class Export:
    """An example's C export in both precisions (folder/double, folder/single)
    and what the tests read of its code model."""
    folder: Path
    name: str
    q0: np.ndarray
    row_columns: list[str]
    row_sizes: list[int]  # the size of each part of a row (the context's row_parts), in order
    t0: float
    t1: float
    steps: int

    def source(self, precision: str) -> Path:
        return self.folder / precision / f"{self.name}_solver.c"

    @property
    def h(self) -> float:
        return (self.t1 - self.t0) / (self.steps - 1)


def example_export(factory: pytest.TempPathFactory, example: str) -> Export:
    """c_target.generate of the example's code model in both precisions (the
    same text as `symid generate`), derived once per run."""
    path = api.example(example)

    def build(folder: Path) -> None:
        mech = load(path)
        model = code_model(mech)
        sizes: list[int] = []
        for precision in PRECISIONS:
            ctx = c_target.context(model, precision=precision)
            c_target.write(ctx, folder / precision)
            sizes = sizes or [size for _, _, size, _ in ctx.row_parts]
        a = mech.analysis
        facts = {"name": model.name, "q0": np.array(model.q0, dtype=float), "row_columns": list(model.row_columns),
                 "row_sizes": sizes, "t0": a.t0, "t1": a.t1, "steps": a.steps}
        (folder / "facts.pickle").write_bytes(pickle.dumps(facts))

    folder = shared_dir(factory, key_of("example export", path, PRECISIONS), build)
    return Export(folder, **pickle.loads((folder / "facts.pickle").read_bytes()))


def case_export(factory: pytest.TempPathFactory, name: str, text: str, precision: str) -> Path:
    """The source `symid generate --target c --precision P` writes for a small
    mechanism's text (tests/helpers/small_mechanisms.py), once per run."""
    def build(folder: Path) -> None:
        (folder / f"{name}.toml").write_text(text)
        code = main(["generate", "--target", "c", "--precision", precision, "-o", str(folder / "c"),
                     str(folder / f"{name}.toml")])
        assert code == 0, (name, precision, code)

    folder = shared_dir(factory, key_of("case export", text, precision), build)
    return next((folder / "c").rglob(f"{name}_solver.c"))


def _command(compiler: list[str]) -> list[str]:
    """The command with its program resolved (cc and gcc may be one compiler: one entry)."""
    found = shutil.which(compiler[0])
    return [os.path.realpath(found) if found else compiler[0], *compiler[1:]]


def object_file(factory: pytest.TempPathFactory, compiler: list[str], source: Path) -> Path:
    """source compiled to an object by `compiler` (program and flags), with no
    warning, once per run for the same source, headers beside it and command."""
    command = _command(compiler)
    headers = sorted(source.parent.glob("*.h"))

    def build(folder: Path) -> None:
        built = subprocess.run([*command, f"-I{source.parent}", "-c", str(source), "-o",
                                str(folder / (source.stem + ".o"))], capture_output=True, text=True)
        assert built.returncode == 0 and "warning" not in built.stderr, (source.name, built.stderr[:3000])

    return shared_dir(factory, key_of("object", command, source, *headers), build) / (source.stem + ".o")


def strict_library(factory: pytest.TempPathFactory, source: Path, into: Path) -> Path:
    """source compiled by `cc STRICT -fPIC -shared` (the strict build a user
    makes of an export) once per run for the same text, headers beside it and
    command, copied into `into` (a library of its own: a second handle of one
    path would share its state); the copy's path."""
    command = _command(["cc", *STRICT, "-fPIC", "-shared"])
    headers = sorted(source.parent.glob("*.h"))

    def build(folder: Path) -> None:
        subprocess.run([*command, f"-I{source.parent}", str(source), "-o", str(folder / "s.so"), "-lm"], check=True)

    built = shared_dir(factory, key_of("strict library", command, source, *headers), build) / "s.so"
    into.mkdir(parents=True, exist_ok=True)
    return Path(shutil.copy2(built, into / "s.so"))


def export_library(factory: pytest.TempPathFactory, source: Path, into: Path) -> Path:
    """An export's source (a mechanism's text as `symid generate` writes it,
    which the embedded build checks warning-free under WARNINGS) built as a
    user builds it, strictly: its HOST_O2 object (object_file: no warning
    under flags that hold STRICT's, -fPIC as the emitted Makefile compiles it;
    once per run for the same text, headers beside it and command: the object
    the rows driver and the double-promotion check link too) linked by
    `cc -shared` into `into` (a library of its own: a second handle of one
    path would share its state); the library's path. A text of another
    context (a test's variant of the checks) is strict_library's."""
    assert set(STRICT) <= set(HOST_O2) and "-fPIC" in HOST_O2
    obj = object_file(factory, HOST_O2, source)
    into.mkdir(parents=True, exist_ok=True)
    subprocess.run([*_command(["cc"]), "-shared", str(obj), "-o", str(into / "s.so"), "-lm"], check=True)
    return into / "s.so"


def host_rows(factory: pytest.TempPathFactory, export: Export, precision: str) -> tuple[Path, np.ndarray]:
    """The rows driver (tests/c/rows_driver.c) linked with the export's host
    object (HOST_O2) in `precision`, and its rows over the file's grid from
    the export's q0: (driver, rows), once per run."""
    source = export.source(precision)
    obj = object_file(factory, HOST_O2, source)
    name = export.name

    def build(folder: Path) -> None:
        exe = folder / "driver"
        subprocess.run(["cc", *WARNINGS, "-O2", f"-I{source.parent}", f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}",
                        f"-DPU={name.upper()}", "-Wno-conversion", str(DRIVER), str(obj), "-lm", "-o", str(exe)],
                       check=True)
        np.save(folder / "rows.npy", driver_rows(exe, export.t0, export.h, export.steps, export.q0))

    folder = shared_dir(factory, key_of("host rows", obj, DRIVER, source.with_suffix(".h"), export.q0.tobytes(),
                                        export.t0, export.t1, export.steps), build)
    return folder / "driver", np.load(folder / "rows.npy")
