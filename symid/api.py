"""The Python API; the command line is a thin layer over it.

    >>> from symid import api
    >>> study = api.prepare(api.example("slider_crank"))
    >>> results = study.solve()
    >>> torque = results["motor.T_j"]
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np
import sympy as sp

from symid import backends
from symid.model.analysis import Analysis
from symid.symbolic.assemble import Layout, assemble
from symid.backends import Array, Evaluator, Needs
from symid.errors import AnalysisError, InputError
from symid.io.reader import load
from symid.model.mechanism import Mechanism
from symid.model.motion import check_spans
from symid.model.params import parameter_values, to_float
from symid.output.results import Results, check_table_size, columns, table_rows, write_csv
from symid.numeric.solve import Instant, run
from symid.backends import check_redundant, require_support
from symid.numeric.stability import Notes, require_square
from symid.text import number, plural


# `[analysis]` keys the functions below take as keyword arguments; `cond_column`
# is `symid solve --cond` (adds the `cond` output to a file's own list).
ANALYSIS_KEYS = tuple(f.name for f in dataclasses.fields(Analysis))
FILE_ONLY_KEYS = ("cond_column",)


def _known(analysis: Mapping[str, Any], function: str, allowed: tuple[str, ...]) -> None:
    """Refuse a keyword argument no analysis has: a typo (`stepz=3`) must not run the default.

    Raises:
        TypeError: naming the unknown keywords and the accepted ones.
    """
    unknown = sorted(k for k in analysis if k not in allowed)
    if unknown:
        raise TypeError(f"{function}() got unexpected keyword argument{'s' if len(unknown) > 1 else ''} "
                        f"{', '.join(map(repr, unknown))} (accepted: {', '.join(allowed)})")


def examples() -> list[str]:
    """Names of the bundled example mechanisms."""
    folder = resources.files("symid") / "examples"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def example(name: str) -> Path:
    """Path of a bundled example's mechanism file (works from an installed package)."""
    path = Path(str(resources.files("symid") / "examples" / f"{name}.toml"))
    if not path.is_file():
        raise FileNotFoundError(f"no bundled example {name!r} (examples: {', '.join(examples())})")
    return path


@dataclass
class Study:
    """A mechanism prepared for one analysis on one backend.

    Attributes:
        mechanism: the (immutable) description; layout: its rows and columns;
        evaluator: the backend's numeric workspace; values: parameter values.
    """

    mechanism: Mechanism
    layout: Layout
    evaluator: Evaluator
    values: Mapping[sp.Symbol, float]
    notes: Notes | None = None  # the warnings of the latest run
    backend: str = ""
    results: Results | None = None  # the latest `solve()`, which `write_csv` writes without solving again

    @property
    def warnings(self) -> list[str]:
        """The latest run's warnings, one line each (empty before a run)."""
        return self.notes.lines() if self.notes is not None else []

    @property
    def analysis(self):  # type: ignore[no-untyped-def]
        return self.mechanism.analysis

    def q0(self) -> Array:
        """The initial guess, size ng."""
        return np.array([to_float(v, self.values) for b in self.mechanism.bodies for v in b.q0])

    def columns(self) -> list[str]:
        return columns(self.layout, self.analysis)

    def instants(self) -> Iterator[Instant]:
        """Solve instant by instant (raises AnalysisError at a failure)."""
        self.notes = Notes(self.analysis)
        return run(self.evaluator, self.analysis, self.q0(), self.notes)

    def rows(self) -> Iterator[Array]:
        """The results table row by row; a compiled backend runs its own loop.

        The run's warnings (`warnings`) include angles that look like degrees
        and bodies assembled at t0 far from their `q0` (`symid.io.misreading`).
        """
        from symid.io.misreading import angle_warnings, assembly_warnings

        self.notes = notes = Notes(self.analysis)
        notes.fixed.extend(angle_warnings(self.mechanism))
        header = self.columns()
        q_at = [header.index(f"{b.name}.{c}") for b in self.mechanism.bodies for c in ("x", "y", "phi")
                if f"{b.name}.{c}" in header]
        first = True
        for row in table_rows(self.evaluator, self.analysis, self.q0(), notes):
            if first and len(q_at) == self.layout.ng:  # the table has q: compare t0's with the guesses
                notes.fixed.extend(assembly_warnings(self.mechanism, self.q0(), np.asarray(row)[q_at]))
            first = False
            yield row

    def solve(self) -> Results:
        """Solve the whole run. A failure is kept in `Results.error` with the
        instants solved before it."""
        width = len(self.columns())
        check_table_size(self.analysis.steps, width, self.mechanism.source)
        rows: list[Array] = []
        error = None
        try:
            for values in self.rows():
                rows.append(values)
        except AnalysisError as exc:
            error = exc
        data = np.array(rows).reshape(len(rows), width)
        self.results = Results(self.columns(), data, error, self.warnings, mechanism=self.mechanism)
        return self.results

    def write_csv(self, path: str | Path) -> int:
        """Write the run to a CSV file (atomic); returns the rows written. The
        results of `solve()`, if it ran; else the run is streamed instant by instant."""
        if self.results is not None:
            return self.results.write_csv(path)
        return write_csv(path, self.columns(), self.rows())

    def summary(self) -> list[str]:
        """What this study solves, its sizes and its state, one line each."""
        m, a = self.mechanism, self.analysis
        lines = [f"{m.name} on {self.backend or type(self.evaluator).__name__}: "
                 f"{plural(len(m.bodies), 'body', 'bodies')}, {plural(len(m.constraints), 'constraint')}, "
                 f"{plural(len(m.forces), 'force')}; ng = {self.layout.ng}, nc = {self.layout.nc}",
                 f"{a.kind}, t = {number(a.t0)} .. {number(a.t1)}, {plural(a.steps, 'instant')}, "
                 f"{plural(len(self.columns()), 'column')}"]
        lines.append("not solved yet (solve())" if self.results is None
                     else f"solved: {self.results.summary()[0]}")
        return lines

    def __repr__(self) -> str:
        return "Study(" + "; ".join(self.summary()) + ")"

    def _repr_html_(self) -> str:
        import html

        first, *rest = self.summary()
        return f"<b>Study</b> {html.escape(first)}<ul>" + "".join(
            f"<li>{html.escape(line)}</li>" for line in rest) + "</ul>"


def prepare(mechanism: Mechanism | str | Path, backend: str = "numpy",
            set_values: Mapping[str, str] | None = None, **analysis: Any) -> Study:
    """Load (if a path), lay out and build the evaluator of a mechanism.

    Args:
        mechanism: a `Mechanism` or the path of a mechanism file.
        backend: one of `symid.backends.names()`.
        set_values: parameter overrides (files only), name -> expression text.
        analysis: `[analysis]` overrides: kind, t0, t1, steps, tol, outputs, reactions.
    """
    _known(analysis, "prepare", ANALYSIS_KEYS if isinstance(mechanism, Mechanism) else ANALYSIS_KEYS + FILE_ONLY_KEYS)
    if isinstance(mechanism, Mechanism):
        mech = mechanism
        if analysis:
            mech = dataclasses.replace(mech, analysis=dataclasses.replace(mech.analysis, **analysis))
            check_spans(mech)  # new t0, t1 must stay inside every table (the reader checked the file's)
    else:
        mech = load(mechanism, set_values, analysis)
    layout = assemble(mech)
    values = parameter_values(mech.parameters)
    a = mech.analysis
    groups = a.output_groups()
    reactions: tuple[str, ...] = ()
    if "reactions" in groups and a.kind != "kinematics":
        reactions = a.reactions if a.reactions is not None else tuple(c.name for c in mech.constraints)
    needs = Needs(velocity=a.kind != "statics", reactions=reactions)
    require_support(backend, a, mech.source)
    check_redundant(layout, values, backend)
    evaluator = backends.get(backend).evaluator(layout, values, needs)
    return Study(mech, layout, evaluator, values, backend=backend)


def load_mechanism(path: str | Path, set_values: Mapping[str, str] | None = None,
                   **analysis: Any) -> Mechanism:
    """Read and validate a mechanism file (see `symid.io.reader.load`)."""
    _known(analysis, "load_mechanism", ANALYSIS_KEYS + FILE_ONLY_KEYS)
    return load(path, set_values, analysis)


def generate(mechanism: Mechanism | str | Path, target: str, out_dir: str | Path,
             precision: str = "double") -> list[Path]:
    """Write the generated code of one target ("c", "numpy", "casadi") into out_dir.

    What is emitted follows the mechanism's `[analysis]`: kind, outputs and reactions.
    precision: "double" or "single" (C only: the type of every floating value).
    """
    from symid.codegen import targets
    from symid.codegen.model import code_model

    module = targets.get(target)
    mech = mechanism if isinstance(mechanism, Mechanism) else load(mechanism)
    require_square(mech)
    if precision != "double":
        if target != "c":
            raise InputError(f"generate: precision {precision!r} applies to the c target only")
        return module.generate(code_model(mech), Path(out_dir), precision=precision)  # type: ignore[no-any-return]
    return module.generate(code_model(mech), Path(out_dir))  # type: ignore[no-any-return]


def generate_examples(out_dir: str | Path, targets: tuple[str, ...] = ("c", "numpy", "casadi")) -> list[Path]:
    """Regenerate the committed `generated/<example>/<target>/` folders."""
    written = []
    for name in examples():
        mech = load(example(name))
        for target in targets:
            written += generate(mech, target, Path(out_dir) / name / target)
    return written


def solve(mechanism: Mechanism | str | Path, backend: str = "numpy", **analysis: Any) -> Results:
    """Prepare and solve in one call; see `prepare` and `Study.solve`."""
    return prepare(mechanism, backend, **analysis).solve()
