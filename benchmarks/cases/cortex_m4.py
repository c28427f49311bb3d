"""Instructions per instant of every example's generated C on an emulated
Cortex-M4F (QEMU's mps2-an386 board, the bare-metal build of
tests/c/test_c_qemu.py), in single and double precision.

Per bundled example and precision:

- instructions_per_instant: instructions executed by the trajectory loop per
  instant, (I(n2) - I(n1)) / (n2 - n1) over runs of n1 and n2 instants from
  the file's t0 (QEMU one instruction per block, its execution log counted:
  the count of the emulated core, independent of the host's load). Double
  precision on this FPU (single only) runs every double operation in
  software: its count is what a double build costs there;
- text, data, bss: the solver's object at -O2 (arm-none-eabi-size).

The stack and the host's cost are the `embedded` case's.

    python -m benchmarks cortex_m4 [--examples a,b]
"""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

from benchmarks.cases import register
from benchmarks.processes import ROOT
from benchmarks.run import Context
from symid import api
from symid.io.reader import load

BOARD = ROOT / "tests" / "c" / "m4"
M4F = ["-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-mthumb"]
QEMU = ["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native"]


def _object(folder: Path, name: str) -> Path:
    """The solver compiled once at -O2: what `_size` measures and both ELFs link (the solver
    uses none of the board program's -D macros, so its object is the same in each)."""
    obj = folder / f"{name}.o"
    subprocess.run(["arm-none-eabi-gcc", "-std=c99", *M4F, "-O2", "-c", str(folder / f"{name}_solver.c"),
                    "-o", str(obj)], check=True, capture_output=True)
    return obj


def _elf(folder: Path, name: str, instants: int, obj: Path) -> Path:
    elf = folder / f"rows{instants}.elf"
    subprocess.run(["arm-none-eabi-gcc", "-std=c99", *M4F, "-O2", "-nostartfiles", "--specs=nosys.specs",
                    f"-T{BOARD / 'mps2_an386.ld'}", f"-I{folder}", f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}",
                    f"-DPU={name.upper()}", f"-DINSTANTS={instants}", "-DQUIET", str(BOARD / "startup.c"),
                    str(BOARD / "rows_main.c"), str(obj), "-lm", "-o", str(elf)],
                   check=True, capture_output=True)
    return elf


def executed(elf: Path) -> int:
    """Instructions the emulated core executes from reset to exit (one per translation block logged)."""
    log = elf.with_suffix(".log")
    run = subprocess.run([*QEMU, "-singlestep", "-d", "exec,nochain", "-D", str(log), "-kernel", str(elf)],
                         stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=3600)
    if run.returncode != 0:
        raise RuntimeError(f"{elf.name}: exit {run.returncode} on the emulated board")
    with log.open("rb") as lines:
        count = sum(1 for line in lines if line.startswith(b"Trace "))
    log.unlink()
    return count


def _size(obj: Path) -> dict[str, int]:
    text, data, bss = subprocess.run(["arm-none-eabi-size", str(obj)], check=True, capture_output=True,
                                     text=True).stdout.splitlines()[1].split()[:3]
    return {"text": int(text), "data": int(data), "bss": int(bss)}


def example(ctx: Context, name: str) -> dict[str, Any]:
    from symid.codegen import c as c_target  # here: every harness process imports this module (the registry)
    from symid.codegen.model import code_model

    model = code_model(load(api.example(name)))
    n1, n2 = (2, 4) if ctx.smoke else (3, 13)
    out: dict[str, Any] = {}
    for precision in ("single", "double"):
        folder = ctx.work / name / precision
        c_target.generate(model, folder, precision=precision)
        obj = _object(folder, name)
        first, second = (executed(_elf(folder, name, n, obj)) for n in (n1, n2))
        out[precision] = {"instructions_per_instant": (second - first) / (n2 - n1), "instants": [n1, n2],
                          **_size(obj)}
    return out


def _options(group: Any) -> None:
    group.add_argument("--examples", help="comma-separated bundled examples (default: all)")


@register("cortex_m4", "instructions per instant on an emulated Cortex-M4F (QEMU), single and double, and code size",
          options=_options, tools=("arm-none-eabi-gcc", "qemu-system-arm"))
def cortex_m4(ctx: Context) -> dict[str, Any]:
    names = ctx.options.examples.split(",") if ctx.options.examples else list(api.examples())
    if ctx.smoke:  # one example reaches every stage; the slider-crank, not the first (the squeezer, 3x its code)
        names = names[:1] if ctx.options.examples else ["slider_crank"]
    out = {}
    for name in names:
        ctx.log(name)
        out[name] = example(ctx, name)
    return out
