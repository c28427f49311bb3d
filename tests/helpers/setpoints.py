"""The generated C solver's set-point entry, compiled for the tests of
tests/c/test_c_setpoint.py and tests/c/test_fmu.py: the solver, the laws'
set-points, the four-bar's drivers written as expression rows, a pendulum."""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from symid.io.reader import load, loads
from symid.model.mechanism import T
from symid.model.params import parameter_values
from symid.symbolic.assemble import assemble
from symid.symbolic.derive import DerivedConstraint
import cbuild
from runshare import key_of, shared_dir
from small_mechanisms import _body, _constraint, _coordinate, text

OK, BAD_ARGUMENT = 0, 5
STRICT = ["cc", *cbuild.STRICT, "-fPIC", "-shared"]
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
# each mechanism text's code model, derived once in this process: code_model
# takes no precision (only c_target.context does), so a double and a single
# build of one file render the same model
_MODELS: dict[str, Any] = {}


class Solver:
    """A generated solver compiled into a shared library, in one precision."""

    def __init__(self, source: str | Path, folder: Path, precision: str = "double", sensitivity: str | None = None,
                 of: str | None = None, share: pytest.TempPathFactory | None = None) -> None:
        """source: a mechanism's text, or its file (read as `symid generate`
        reads it: the header's parameter comments are the file's, the text an
        export's). share: the files and library built once per test run for
        every Solver of the same text, precision and sensitivity (runshare),
        copied into folder (a library of its own: a second handle of one path
        would share its state)."""
        if isinstance(source, Path):
            self.mech, source = load(source), f"{source}\n{source.read_text()}"
        else:
            self.mech = loads(source, "mech.toml")
        if sensitivity:
            model = api._sensitivity_model(self.mech, "c", sensitivity, of)
        else:  # the file's code model, derived once per text for both precisions (a frozen dataclass)
            if source not in _MODELS:
                _MODELS[source] = code_model(self.mech)
            model = _MODELS[source]
        self.ctx = c_target.context(model, precision=precision)
        self.name = model.name

        def build(into: Path) -> None:
            c_target.write(self.ctx, into)  # c_target.generate's files, of the context built once
            if share is not None:  # one strict build per run of this text (an example's: its export's object)
                cbuild.export_library(share, into / f"{self.name}_solver.c", into)
                return
            subprocess.run([*STRICT, str(into / f"{self.name}_solver.c"), "-o", str(into / "s.so"), "-lm"],
                           check=True)

        if share is None:
            build(folder)
        else:
            built = shared_dir(share, key_of("setpoint-solver", source, precision, sensitivity, of, STRICT,
                                             cbuild.HOST_O2), build)
            shutil.copytree(built, folder, dirs_exist_ok=True)
        self.ng, self.nc, self.nr = self.ctx.ng, self.ctx.nc, self.ctx.nr
        self.real = np.float64 if precision == "double" else np.float32
        self.ct = ctypes.c_double if precision == "double" else ctypes.c_float
        self.q0 = np.array(model.q0, dtype=self.real)
        self.p = np.array(model.flat.defaults, dtype=self.real)
        self.lib = ctypes.CDLL(str(folder / "s.so"))
        self.nd = self.ctx.setpoint.nd
        self.rows = list((ctypes.c_int * self.nd).in_dll(self.lib, f"{self.name}_setpoint_rows"))
        self.columns = model.row_columns
        self.mech_params = list(model.flat.params)

    def reaction(self, column: str) -> int:
        """The index in reactions of a reaction column (row order: they come last)."""
        first = next(k for k, c in enumerate(self.columns) if c.endswith(("Fx_i", "Fx_j", "Fx")))
        return self.columns.index(column) - first

    def _ptr(self, a: np.ndarray | None) -> Any:
        return None if a is None else a.ctypes.data_as(ctypes.c_void_p)

    def call(self, entry: str, t: float | tuple[int, float], q: np.ndarray, des: tuple[np.ndarray | None, ...] = (),
             tol: float = 1e-12) -> tuple[int, dict[str, np.ndarray]]:
        """instant or setpoint (or their _at forms, t then (whole, frac)) from
        the guess q: status and outputs."""
        out = {"q": np.array(q, dtype=self.real), "qd": np.zeros(self.ng, self.real),
               "qdd": np.zeros(self.ng, self.real), "lam": np.zeros(self.nc, self.real),
               "reactions": np.zeros(max(self.nr, 1), self.real)}
        work, iwork = np.zeros(self.ctx.work, self.real), np.zeros(self.ng, np.intc)
        fn = getattr(self.lib, f"{self.name}_{entry}")
        fn.restype = ctypes.c_int
        when = [ctypes.c_long(t[0]), self.ct(t[1])] if isinstance(t, tuple) else [self.ct(t)]
        args = [*when, self._ptr(self.p), self.ct(tol)]
        if entry.startswith("setpoint"):
            args += [self._ptr(None if d is None else np.asarray(d, self.real)) for d in des]
        args += [self._ptr(out[k]) for k in ("q", "qd", "qdd", "lam", "reactions")]
        args += [None, self._ptr(work), self._ptr(iwork)]
        status = fn(*args)
        return status, out

class Laws:
    """Each driver's f, f', f'' (drivers in constraint-row order), by sympy
    from the file's expressions with the parameters' values: the layout
    assembled and the derivatives taken once, then evaluated at each t."""

    def __init__(self, mech: Any) -> None:
        layout = assemble(mech)
        values = parameter_values(mech.parameters)
        found = []
        for group in layout.constraint_groups:
            assert isinstance(group.derived, DerivedConstraint)
            if group.derived.functions:
                for m in range(group.size):
                    found.append((int(group.rows[m]), sp.sympify(group.functions[m][0]).xreplace(values)))
        found.sort(key=lambda x: x[0])
        self.derivatives = [[sp.diff(f, T, n) for _, f in found] for n in range(3)]

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f, f', f'' at t, evaluated to 30 digits at t (a float), rounded to float."""
        out = [[float(d.evalf(30, subs={T: t})) for d in row] for row in self.derivatives]
        return np.array(out[0]), np.array(out[1]), np.array(out[2])


def laws(mech: Any, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each driver's f, f', f'' at t (Laws at one instant)."""
    return Laws(mech)(t)


def expression_drivers(source: str) -> str:
    """A mechanism file with each relative_angle_driver written as an expression
    driver row `phi_j - phi_i - (C) - (f)` (`phi_i - (C) - (f)` on the body
    alone when i is the ground): the reference's Phi of the driver, the same
    sign, so the same f and the same multiplier."""
    def driver(m: re.Match) -> str:
        block = m.group(0)
        get = lambda k: (re.search(rf'^{k} = "?(.*?)"?\s*(#.*)?$', block, re.M) or [None, None])[1]  # noqa: E731
        i, j, f, c = get("i"), get("j"), get("f"), get("C") or "0"
        rows, bodies = ((f"phi_i - ({c}) - ({f})", f'i = "{j}"\n') if i == "ground" else
                        (f"phi_j - phi_i - ({c}) - ({f})", f'i = "{i}"\nj = "{j}"\n'))
        return f'[[constraint]]\nname = "{get("name")}"\ntype = "expression"\n{bodies}phi = ["{rows}"]\n\n'
    out = re.sub(r'\[\[constraint\]\]\nname = .*\ntype = "relative_angle_driver"\n(?:.+\n)*\n', driver, source)
    assert "relative_angle_driver" not in out and 'type = "expression"' in out
    return out

# to the ground at l behind it, its angle phi driven by a coordinate driver
# (the law in the file, sin(t), is never read by setpoint). The centre of
# mass is at l (cos phi, sin phi); gravity g down. Moments about the pin:
# (J + m l^2) phi'' = tau - m g l cos phi, tau the driver's torque on the bar.
M, J, L, G = 2.5, 0.3, 0.4, 9.81
PENDULUM = text("pendulum_ct",
                _body("bar", f"{L}, 0.0, 0.0", mass=str(M), inertia=str(J))
                + _constraint("pin", "revolute", i='"ground"', j='"bar"', si="[0.0, 0.0]", sj=f"[{-L}, 0.0]")
                + _coordinate("bar", "phi", "sin(t)"),
                gravity=-G)
# the same pendulum driven by an expression row: its set-point is the f of
