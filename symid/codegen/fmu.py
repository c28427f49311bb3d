"""The FMU target: the C solver's set-point entry as an FMI 2.0 model-exchange FMU.

`symid generate FILE --target fmu` writes `<name>.fmu`: the generated C
solver and a small FMI 2.0 wrapper (templates/fmu/fmi2.c.j2), compiled with
the system's C compiler into `binaries/<platform>/<name>.<so|dylib|dll>`,
`modelDescription.xml` and the sources (`sources/`), zipped.

Model exchange, not co-simulation: inverse dynamics has no state to
integrate. Its outputs (efforts, reactions, q and its rates) are algebraic
functions of the inputs (each driver's set-point q, qd, qdd) and time, which
model exchange with no continuous state represents exactly: an importer
reads the outputs at t from the inputs it set at t. FMI 2.0 co-simulation
would read them after `fmi2DoStep` from the inputs set before the step: one
communication step late for a computed-torque feed-forward.

The parameters are tunable: a change takes effect at the next evaluation.
The wrapper keeps the last solution as the next Newton guess. A solve that
fails makes `fmi2GetReal` of an output return fmi2Error, logged with the time
and the solver's status (category logStatusError).
"""

from __future__ import annotations

import hashlib
import math
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import sympy as sp

from symid.codegen.model import CodeModel
from symid.codegen.render import render
from symid.codegen import c as c_target
from symid.errors import InputError
from symid.codegen.compiler import _compile, find
from symid.model.mechanism import T
from symid.model.params import parameter_values
from symid.symbolic.derive import DerivedConstraint

NAME = "fmu"
# (FMI platform folder, shared library suffix) per sys.platform: the FMU is
# built for the machine that generates it, with its compiler
PLATFORMS = {"linux": ("linux64", ".so"), "darwin": ("darwin64", ".dylib"), "win32": ("win64", ".dll")}
CFLAGS = ("-std=c99", "-O2", "-fno-math-errno", "-fPIC", "-shared")
# the solver's array each output group is read from (fmi2.c.j2's output())
ARRAYS = {"q": 0, "qd": 1, "qdd": 2, "lam": 3, "reac": 4}


def _law_values(model: CodeModel, t: float) -> list[tuple[float, float, float]]:
    """Each driver's f, f', f'' at t (constraint-row order): the inputs' start values."""
    layout = model.layout
    values = parameter_values(layout.mechanism.parameters)
    found = []
    for group in layout.constraint_groups:
        assert isinstance(group.derived, DerivedConstraint)
        if group.derived.functions:
            for m in range(group.size):
                f = sp.sympify(group.functions[m][0]).xreplace(values)
                found.append((int(group.rows[m]), tuple(float(sp.diff(f, T, n).subs(T, t).evalf(20))
                                                        for n in range(3))))
    return [v for _, v in sorted(found)]  # type: ignore[misc]


def _xml_number(v: float) -> str:
    """A real as modelDescription.xml writes it (finite: a law undefined at t0,
    a table's span past it, starts at 0)."""
    return repr(float(v)) if math.isfinite(v) else "0.0"


def context(model: CodeModel) -> tuple[c_target.CContext, dict[str, Any]]:
    """The solver's context and what the wrapper and modelDescription.xml
    templates need besides it (`fmu`)."""
    ctx = c_target.context(model)
    sp_ctx = ctx.setpoint
    if sp_ctx is None:
        raise InputError(f"{model.layout.mechanism.source}: --target fmu: the mechanism has no driver, so no "
                         f"set-point to take as an input")
    f = model.flat
    velocity = f.options.velocity
    starts = _law_values(model, ctx.d.t0)
    variables: list[dict[str, Any]] = []
    for name, value, info in zip(f.params, f.defaults, ctx.d.param_info):
        variables.append({"name": name, "causality": "parameter", "variability": "tunable",
                          "start": _xml_number(value), "description": info.get("comment") or ""})
    kinds = (("q_des", "value"), ("qd_des", "rate"), ("qdd_des", "second rate"))[:3 if velocity else 1]
    inputs = []
    for k, (driver, start) in enumerate(zip(sp_ctx.drivers, starts)):
        for n, (suffix, what) in enumerate(kinds):
            inputs.append((n, k))
            law = "f of its row g(q) - f(t)" if driver.type == "expression" else f"the {driver.type}'s f"
            variables.append({"name": f"{driver.name}.{suffix}", "causality": "input", "variability": "continuous",
                              "start": _xml_number(start[n]), "description": f"set-point: the {what} of {law}"})
    outputs = []  # (array, index) per output
    units = {c["name"]: c["unit"] for c in ctx.d.columns}
    for group, source, size, offset in ctx.row_parts:
        if source is None:  # statics' rates: zero, not computed
            continue
        for i in range(size):
            column = model.row_columns[offset + i]
            outputs.append((ARRAYS[source], i))
            variables.append({"name": column, "causality": "output", "variability": "continuous",
                              "description": units.get(column) or ""})
    for k, v in enumerate(variables):
        v["vr"] = k
        v["index"] = k + 1
    first_output = len(f.params) + len(inputs)
    return ctx, {

        "variables": variables, "inputs": inputs, "outputs": outputs, "first_output": first_output,
        "nin": len(inputs), "nout": len(outputs), "input_starts": [v["start"] for v in variables
                                                                  if v["causality"] == "input"],
        "step": _xml_number((ctx.d.t1 - ctx.d.t0) / max(ctx.d.steps - 1, 1)),
        "t0": _xml_number(ctx.d.t0), "t1": _xml_number(ctx.d.t1), "tol": _xml_number(ctx.d.tol),
        "sources": [f"{f.name}_solver.c", f"{f.name}_fmi2.c"],
    }


def _guid(fmu: dict[str, Any], solver: Path) -> str:
    """The FMU's GUID: a hash of its variables and its solver's source, so an
    FMU whose interface or code changed does not pass for an older one."""
    text = "\n".join(f"{v['name']}|{v['causality']}|{v.get('start', '')}" for v in fmu["variables"])
    h = hashlib.sha256((text + "\n").encode() + solver.read_bytes()).hexdigest()
    return "{%s-%s-%s-%s-%s}" % (h[:8], h[8:12], h[12:16], h[16:20], h[20:32])


WHO = "generate --target fmu"


def compiler() -> str:
    """The C compiler ($CC, else cc, gcc or clang); an input error (exit 2)
    naming what to do when there is none."""
    return find(WHO, "--target c writes the sources without compiling", " to build the FMU's binary")


def _build(cc: str, sources: list[Path], library: Path) -> None:
    """Compile the sources into the shared library; a failure is one line (exit 2)."""
    _compile(cc, [*CFLAGS, *map(str, sources), "-o", str(library), "-lm"], library, WHO, "the FMU's sources")


def _zip(folder: Path, target: Path) -> None:
    """The folder's files into target, in name order with a fixed date: the
    same sources give the same archive entries."""
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as z:
        for path in sorted(p for p in folder.rglob("*") if p.is_file()):
            info = zipfile.ZipInfo(path.relative_to(folder).as_posix(), date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, path.read_bytes())


def generate(model: CodeModel, out_dir: Path, precision: str = "double") -> list[Path]:
    """Write `<name>.fmu` into out_dir (double precision: FMI's reals are doubles)."""
    if precision != "double":
        raise InputError(f"generate: precision {precision!r} applies to the c target only")
    if sys.platform not in PLATFORMS:
        raise InputError(f"generate --target fmu: no FMI platform name for {sys.platform}")
    cc = compiler()  # before any work: no compiler is said at once
    ctx, fmu = context(model)
    name = model.name
    platform, suffix = PLATFORMS[sys.platform]
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="symid-fmu-") as tmp:
        root = Path(tmp) / "fmu"
        sources = root / "sources"
        c_target.write(ctx, sources)
        fmu["guid"] = _guid(fmu, sources / f"{name}_solver.c")
        names = {**ctx.namespace(), "fmu": fmu}
        (sources / "Makefile").unlink()  # the FMU's build is the modelDescription's SourceFiles
        (sources / f"{name}_fmi2.c").write_text(render("fmu/fmi2.c.j2", **names))
        (root / "modelDescription.xml").write_text(render("fmu/modelDescription.xml.j2", **names))
        binaries = root / "binaries" / platform
        binaries.mkdir(parents=True)
        _build(cc, [sources / f for f in fmu["sources"]], binaries / f"{name}{suffix}")
        target = out_dir / f"{name}.fmu"
        _zip(root, target)
    return [target]
