"""The C export as an embedded engineer sees it, per bundled example.

    python -m benchmarks embedded [--examples a,b]

For each example:

- us_per_instant: the host (cc -O2 -fno-math-errno) cost of one instant in
  the trajectory loop and of `_instant` continued from the last solution,
  double and single precision (the minimum over repeats: a shared machine);
- single_over_double: the single-precision time of each over the double's;
- single_error: single against double precision, per row column, max |diff|
  over the bundled run divided by the column's peak (`short`), and the same
  over one bundled run's length of instants starting at t = 1e4 s (`long`:
  t0 a whole number of the run's periods, the guess's angles turned the
  whole turns of as many runs); the worst column of each. Angles are
  compared modulo 2 pi (single carries angles that keep turning reduced by
  whole turns, see the header) against a peak of at most pi;
- long_bound_applies: whether the single header lists nothing kept
  absolute (`kept`: a pulse in t, angles geared by a ratio), the examples
  the README's long-run bound is stated for;
- arm: arm-none-eabi-gcc -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard
  (-O2 and -Os, single and double): text + data bytes of the object
  (arm-none-eabi-size) and the worst stack depth of `_trajectory` and
  `_instant` (their frames plus the deepest chain of callees, from
  -fstack-usage and -fcallgraph-info).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from symid import api
from symid.io.reader import load

from benchmarks.cases import register
from benchmarks.processes import ROOT
from benchmarks.run import Context

DRIVER = ROOT / "tests" / "c" / "rows_driver.c"
ARM = ("-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-mthumb")
LONG_T0 = 1e4
GROUP_FLOOR = 1e-3


def build(name: str, precision: str, folder: Path) -> tuple[Path, Any]:
    """Generate one example's C in one precision and link the driver."""
    from symid.codegen import c as c_target  # here: every harness process imports this module (the registry)
    from symid.codegen.model import code_model

    model = code_model(load(api.example(name)))
    c_target.generate(model, folder, precision=precision)
    exe = folder / "driver"
    subprocess.run(["cc", "-std=c99", "-O2", "-fno-math-errno", f"-I{folder}",
                    f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}", f"-DPU={name.upper()}", str(DRIVER),
                    str(folder / f"{name}_solver.c"), "-lm", "-o", str(exe)], check=True)
    return exe, model


def _call(exe: Path, mode: str, t0: float, h: float, n: int, q0: Any) -> str:
    args = [str(exe), mode, repr(t0), repr(h), str(n), *(repr(float(v)) for v in q0)]
    return subprocess.run(args, check=True, capture_output=True, text=True).stdout


def rows(exe: Path, t0: float, h: float, n: int, q0: Any) -> np.ndarray:
    return np.loadtxt(_call(exe, "rows", t0, h, n, q0).splitlines(), ndmin=2)


def relative_error(single: np.ndarray, double: np.ndarray, groups: list[int], angles: Sequence[int] = (),
                   peak: np.ndarray | None = None) -> np.ndarray:
    """Per column: max |single - double| / the column's peak |double| (or the
    `peak` given: the bundled run's). A column whose peak is below
    GROUP_FLOOR of its output group's (q, qdot, qddot, lambda, reactions:
    `groups` numbers them per column) is zero in exact arithmetic, rounding
    noise in double: it is measured against GROUP_FLOOR times the group's
    peak instead. Columns in `angles` are compared modulo 2 pi, against a
    peak of at most pi (their reduced range)."""
    diff = single - double
    angles = list(angles)
    diff[:, angles] -= 2 * np.pi * np.round(diff[:, angles] / (2 * np.pi))
    peak = np.max(np.abs(double), axis=0) if peak is None else peak.copy()
    peak[angles] = np.minimum(peak[angles], np.pi)
    index = np.array(groups)
    group_peak = np.array([np.max(peak[index == g]) for g in index])
    scale = np.maximum(peak, GROUP_FLOOR * group_peak)
    return np.max(np.abs(diff), axis=0) / np.where(scale > 0, scale, 1.0)


def long_guess(model: Any, run: np.ndarray, k: int) -> np.ndarray:
    """The guess k runs on: q0 with each angle advanced k times what the run
    turned it, where that is whole turns (a periodic motion); else q0."""
    q0 = np.array(model.q0)
    turned = run[-1, 1:1 + len(q0)] - run[0, 1:1 + len(q0)]
    turns = np.round(turned / (2 * np.pi))
    angles = (np.arange(len(q0)) % 3 == 2) & (np.abs(turned - 2 * np.pi * turns) < 1e-6)
    return np.where(angles, q0 + k * 2 * np.pi * turns, q0)


def _stack(folder: Path, name: str) -> dict[str, int]:
    """Worst stack depth of the public entry points: each function's frame
    (.su) plus its deepest chain of callees (the .ci call graph)."""
    frames: dict[str, int] = {}
    for line in (folder / f"{name}_solver.su").read_text().splitlines():
        fields = line.split("\t")
        frames[fields[0].rsplit(":", 1)[-1]] = int(fields[1])
    calls: dict[str, set[str]] = {}
    graph = (folder / f"{name}_solver.ci").read_text()
    for src, dst in re.findall(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', graph):
        calls.setdefault(src.rsplit(":", 1)[-1], set()).add(dst.rsplit(":", 1)[-1])

    def depth(fn: str, seen: frozenset[str] = frozenset()) -> int:
        below = [depth(g, seen | {fn}) for g in calls.get(fn, ()) if g not in seen]
        return frames.get(fn, 0) + max(below, default=0)

    return {fn: depth(f"{name}_{fn}") for fn in ("trajectory", "instant")}


def arm(name: str, precision: str, level: str, folder: Path) -> dict[str, Any]:
    """Compile for a Cortex-M4F (-c): object size and worst stack depth."""
    obj = folder / f"{name}_solver.o"
    subprocess.run(["arm-none-eabi-gcc", "-std=c99", level, *ARM, "-fno-math-errno", "-fstack-usage",
                    "-fcallgraph-info=su", "-c", str(folder / f"{name}_solver.c"), "-o", str(obj)], check=True,
                   cwd=folder)
    size = subprocess.run(["arm-none-eabi-size", str(obj)], check=True, capture_output=True, text=True).stdout
    text, data, bss = (int(v) for v in size.splitlines()[1].split()[:3])
    return {"text": text, "data": data, "bss": bss, "stack": _stack(folder, name)}


def example(name: str, quick: bool, work: Path) -> dict[str, Any]:
    """Every figure of one example (`quick`, a smoke run's: 64 instants, the Cortex-M4F
    object at -O2 only, -Os being the same steps with another flag)."""
    from symid.codegen import c as c_target

    out: dict[str, Any] = {}
    exes, models = {}, {}
    for precision in ("double", "single"):
        exes[precision], models[precision] = build(name, precision, work / f"{name}_{precision}")
    model = models["double"]
    a = load(api.example(name)).analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    n = min(a.steps, 64) if quick else a.steps
    out["us_per_instant"] = {}
    for precision, exe in exes.items():
        loop, instant = (float(v) for v in _call(exe, "time", a.t0, h, n, model.q0).split())
        out["us_per_instant"][precision] = {"trajectory": loop, "instant": instant}
    us = out["us_per_instant"]
    out["single_over_double"] = {k: us["single"][k] / us["double"][k] for k in ("trajectory", "instant")}
    kept = c_target.context(model, precision="single").phase.kept
    out["long_bound_applies"], out["kept"] = not kept, kept
    out["single_error"] = {}
    columns = list(model.row_columns)
    parts = c_target.context(model).row_parts
    groups = [0] + [k + 1 for k, (_, _, size, _) in enumerate(parts) for _ in range(size)]
    groups += [len(parts) + 1] * (len(columns) - len(groups))  # joint friction's columns: a group of their own
    short = {p: rows(exe, a.t0, h, n, model.q0) for p, exe in exes.items()}
    period = (n - 1) * h
    k = round(LONG_T0 / period)
    guess = long_guess(model, short["double"], k)
    for label, t0 in (("short", a.t0), ("long", a.t0 + k * period)):
        try:
            runs = short if label == "short" else {p: rows(exe, t0, h, n, guess) for p, exe in exes.items()}
        except subprocess.CalledProcessError as exc:
            out["single_error"][label] = {"t0": t0, "failed": exc.stderr.strip()}
            continue
        angles = [1 + j for j in range(len(model.q0)) if j % 3 == 2]
        err = relative_error(runs["single"], runs["double"], groups, angles, np.max(np.abs(short["double"]), axis=0))
        worst = int(np.argmax(err[1:])) + 1
        out["single_error"][label] = {"t0": t0, "instants": n, "worst": float(err[worst]),
                                      "worst_column": columns[worst], "columns": dict(zip(columns, map(float, err)))}
    if shutil.which("arm-none-eabi-gcc"):
        out["arm"] = {f"{precision} {level}": arm(name, precision, level, work / f"{name}_{precision}")
                      for precision in ("single", "double") for level in (("-O2",) if quick else ("-O2", "-Os"))}
    else:
        out["arm"] = "skipped: arm-none-eabi-gcc not installed"
    return out


def _options(group: Any) -> None:
    group.add_argument("--examples", help="comma-separated (default: every bundled example)")


@register("embedded", "the C export per example: us per instant in double and single, single's error against "
          "double (short and at t = 1e4 s), Cortex-M4F code size and stack", options=_options, tools=("cc",))
def embedded(ctx: Context) -> dict[str, Any]:
    names = (ctx.options.examples.split(",") if ctx.options.examples
             else ["slider_crank"] if ctx.smoke else api.examples())
    results: dict[str, Any] = {}
    for name in names:
        r = results[name] = example(name, ctx.smoke, ctx.work)
        us = r["us_per_instant"]
        ctx.log(f"{name:16s} us/instant double {us['double']['trajectory']:.2f}, single "
                f"{us['single']['trajectory']:.2f}; single vs double: short {r['single_error']['short']['worst']:.1e}"
                f" ({r['single_error']['short']['worst_column']})")
    return results
