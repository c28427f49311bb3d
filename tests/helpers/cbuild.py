"""Building the generated C in the tests: the strict flags every build uses,
the embedded build's warnings and Cortex-M4F target, and the mark that skips
a test on a machine without a C compiler; the single-precision bounds and
the rows driver (tests/c/rows_driver.c) built for one export."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid.codegen import c as c_target

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


def rows_driver(folder: Path, name: str, precision: str, model) -> Path:  # type: ignore[no-untyped-def]
    c_target.generate(model, folder, precision=precision)
    exe = folder / "driver"
    subprocess.run(["cc", *WARNINGS, "-O2", f"-I{folder}", f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}",
                    f"-DPU={name.upper()}", "-Wno-conversion", str(DRIVER),
                    str(folder / f"{name}_solver.c"), "-lm", "-o", str(exe)], check=True)
    return exe


def driver_rows(exe: Path, t0: float, h: float, n: int, q0) -> np.ndarray:  # type: ignore[no-untyped-def]
    args = [str(exe), "rows", repr(t0), repr(h), str(n), *(repr(float(v)) for v in q0)]
    return np.loadtxt(subprocess.run(args, check=True, capture_output=True, text=True).stdout.splitlines(), ndmin=2)
