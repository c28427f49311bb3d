"""The generated C run on an emulated Cortex-M4F (QEMU's mps2-an386 board,
system emulation, arm-none-eabi-gcc, hard float on fpv4-sp-d16): every
bundled example's trajectory over its file's grid, in double (each double
operation in software) within 1e-12 of each column's peak of the host's
double build, and in single within the bound the single-precision header
states (<NAME>_SINGLE_BOUND: 1e-5 of each column's peak, joint friction's
5e-2; the slider-crank within docs/c-export.md's 2e-6). Skipped, naming what is missing, where QEMU or the cross
compiler is not installed (.ci/run installs both where apt-get may)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid import api
from cbuild import GROUP_FLOOR, M4F, PRECISIONS, WARNINGS, Export, example_export, host_rows, object_file, single_bound

pytestmark = pytest.mark.slow

BOARD = Path(__file__).resolve().parent / "m4"
EXAMPLES = tuple(api.examples())
# newlib's libm against glibc's (sin, cos, sqrt, atan2 each within an ulp or
# two), then Newton to the file's tolerance from the same guess: agreement
# to a few 1e-15 of a column's peak; 1e-12 is the bound.
DOUBLE_BOUND = 1e-12


def _tools() -> None:
    missing = [tool for tool in ("arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(tool) is None]
    if missing:
        pytest.skip(f"{' and '.join(missing)} not installed (.ci/run installs gcc-arm-none-eabi and "
                    "qemu-system-arm where apt-get may): the emulated Cortex-M4F run is not checked")


# The solver's optimizer level per precision: the strict Cortex-M4F build's
# (tests/c/test_c_embedded.py), whose objects these are: each level run on the
# emulator once, as each is compiled there once (the single objects are the
# double-helper link's too).
LEVEL = {"single": "-O2", "double": "-Os"}


def _run_on_m4(factory: pytest.TempPathFactory, export: Export, precision: str, folder: Path) -> np.ndarray:
    """The export's solver object for the M4F (the run's shared one, no
    warning) linked with the board's start-up and rows_main.c, run on QEMU."""
    name = export.name
    obj = object_file(factory, ["arm-none-eabi-gcc", *WARNINGS, *M4F, LEVEL[precision]], export.source(precision))
    elf = folder / f"rows_{precision}.elf"
    built = subprocess.run(["arm-none-eabi-gcc", *WARNINGS, "-Wno-conversion", *M4F, "-O2", "-nostartfiles",
                    "--specs=nosys.specs", f"-T{BOARD / 'mps2_an386.ld'}", f"-I{export.folder / precision}",
                    f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}", f"-DPU={name.upper()}",
                    str(BOARD / "startup.c"), str(BOARD / "rows_main.c"), str(obj),
                    "-lm", "-o", str(elf)], capture_output=True, text=True)
    assert built.returncode == 0, (name, built.stderr[-3000:])
    run = subprocess.run(["qemu-system-arm", "-M", "mps2-an386", "-nographic",
                          "-semihosting-config", "enable=on,target=native", "-kernel", str(elf)],
                         stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, (name, run.returncode, run.stderr[-2000:])
    # QEMU writes the semihosting text to its standard error (not a terminal here)
    bits = np.array([int(w, 16) for w in (run.stdout + run.stderr).split() if len(w) == 16], dtype=np.uint64)
    assert bits.size, (name, run.stdout[-500:], run.stderr[-500:])
    return bits.view(np.float64)


@pytest.mark.parametrize("example", EXAMPLES)
def test_every_example_on_an_emulated_cortex_m4f_matches_the_host(tmp_path_factory, tmp_path: Path,
                                                                 example: str) -> None:
    _tools()
    export = example_export(tmp_path_factory, example)
    host = host_rows(tmp_path_factory, export, "double")[1]  # shared with the single-precision rows test
    peak = np.max(np.abs(host), axis=0)
    # a column zero but for rounding is measured against 1e-3 of the run's peak
    scale = np.maximum(peak, GROUP_FLOOR * peak.max())
    for precision in PRECISIONS:
        rows = _run_on_m4(tmp_path_factory, export, precision, tmp_path).reshape(host.shape)
        error = np.max(np.abs(rows - host), axis=0) / scale
        worst = int(np.argmax(error))
        bound = DOUBLE_BOUND if precision == "double" else single_bound(export.folder / precision, example)
        assert error[worst] <= bound, (precision, export.row_columns[worst], error[worst])
        if precision == "single":
            assert error.max() > 1e-9  # the single run is single: it differs from double
