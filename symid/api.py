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
from typing import Any, Iterator, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.backends import friction
from symid.backends.prepare import Solver, needs_of
from symid.backends.prepare import prepare as prepare_solver
from symid.model.analysis import Analysis
from symid.symbolic.assemble import Layout, assemble
from symid.backends import Array, Evaluator
from symid.errors import AnalysisError, InputError
from symid.io.reader import load
from symid.model.mechanism import Mechanism
from symid.model.motion import check_spans
from symid.output.results import Results, check_table_size, columns, table_blocks
from symid.output.tables import blocks, write_table
from symid.numeric.solve import Instant, run
from symid.numeric.redundancy import require_square
from symid.numeric.stability import Notes
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
        evaluator: the backend's numeric workspace; values: parameter values;
        solver: all of these as built (`symid.backends.prepare`), with what
        the backend declares it can do.
    """

    mechanism: Mechanism
    layout: Layout
    evaluator: Evaluator
    values: Mapping[sp.Symbol, float]
    notes: Notes | None = None  # the warnings of the latest run
    backend: str = ""
    results: Results | None = None  # the latest `solve()`, which `write_csv` writes without solving again
    sensitivity: Any = None  # `symid.output.sensitivity.Choice`: the d(COLUMN)/d(NAME) columns, or None
    solver: Solver | None = None  # None only for a Study put together by hand

    @property
    def warnings(self) -> list[str]:
        """The latest run's warnings, one line each (empty before a run)."""
        return self.notes.lines() if self.notes is not None else []

    @property
    def analysis(self):  # type: ignore[no-untyped-def]
        return self.mechanism.analysis

    def q0(self) -> Array:
        """The initial guess, size ng."""
        if self.solver is not None and self.solver.values is self.values:
            return self.solver.q0()
        from symid.model.params import initial_guess

        return initial_guess(self.mechanism, self.values)

    def columns(self) -> list[str]:
        own = columns(self.layout, self.analysis)
        return own if self.sensitivity is None else own + self.sensitivity.header

    def instants(self) -> Iterator[Instant]:
        """Solve instant by instant (raises AnalysisError at a failure)."""
        self.notes = Notes(self.analysis)
        return run(self.evaluator, self.analysis, self.q0(), self.notes)

    def rows(self) -> Iterator[Array]:
        """The results table row by row; a compiled backend runs its own loop.
        (The rows of `blocks`, one by one.)"""
        for block in self.blocks():
            if np.ndim(block) == 2:
                yield from block
            else:
                yield block

    def blocks(self) -> Iterator[Array]:
        """The results table as rows (1-D) or blocks of rows (2-D, a compiled
        loop's chunks), in order; the writers take both.

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
        for item in self._source(notes):
            if first and len(q_at) == self.layout.ng:  # the table has q: compare t0's with the guesses
                row = np.asarray(item)
                row = row[0] if row.ndim == 2 else row
                notes.fixed.extend(assembly_warnings(self.mechanism, self.q0(), row[q_at]))
            first = False
            yield item

    def _source(self, notes: Notes) -> Iterator[Array]:
        """The table's rows or blocks: the backend's, or with sensitivities the
        shared Python loop's (whose factorization of Phi_q they reuse)."""
        if self.sensitivity is None or (self.evaluator.capabilities.sensitivities and  # a compiled loop's own
                                        self.evaluator.sensitivity_header == self.sensitivity.header):  # type: ignore[attr-defined]
            return table_blocks(self.evaluator, self.analysis, self.q0(), notes)
        from symid.output import sensitivity

        sens = sensitivity.evaluator_for(self.layout, self.values, self.sensitivity, self.analysis)
        return sensitivity.rows(self.evaluator, self.analysis, self.q0(), notes, self.sensitivity, sens)

    def solve(self) -> Results:
        """Solve the whole run. A failure is kept in `Results.error` with the
        instants solved before it."""
        width = len(self.columns())
        check_table_size(self.analysis.steps, width, self.mechanism.source)
        parts: list[Array] = []
        error = None
        try:
            for block in blocks(self.blocks(), width):
                parts.append(block)
        except AnalysisError as exc:
            error = exc
        data = np.concatenate(parts) if parts else np.empty((0, width))
        self.results = Results(self.columns(), data, error, self.warnings, mechanism=self.mechanism)
        return self.results

    def solve_many(self, P: Any, names: Sequence[str] | None = None, chunk: int = 64) -> Iterator[list[Results]]:
        """Solve K variants of this study, yielding their `Results` in order,
        `chunk` at a time: memory holds one chunk of whole trajectories, not K.

        Args:
            P: shape (K, len(names)), one variant per row.
            names: the base parameters the columns of P set (default: every
                base parameter, in the order of the generated code's `p`);
                the others keep this study's values. A derived parameter is
                refused (it follows from its definition).

        A variant that fails keeps its `Results` with `error` set and the
        instants solved before it; the next variants run on.
        """
        if self.sensitivity is not None:  # the batch engine has no sensitivities: never a header without its data
            raise ValueError("Study.solve_many(): sensitivities are solved variant by variant; prepare each "
                             "variant with api.prepare(..., set_values=..., sensitivity=...) and solve() it")
        from symid.model.params import base_names
        from symid.study.engine import trajectories, variant_mechanism
        from symid.study.variants import base_matrix

        mech = dataclasses.replace(self.mechanism, parameters={  # this study's values (--set included)
            n: (sp.Float(self.values[sp.Symbol(n, real=True)]) if n in base_names(self.mechanism.parameters) else e)
            for n, e in self.mechanism.parameters.items()})
        chosen = tuple(names) if names is not None else base_names(mech.parameters)
        full = base_matrix(mech, chosen, P)
        header = self.columns()
        out: list[Results] = []
        runs = trajectories(mech, self.layout, full, self.backend or "numpy", self.solver)
        for row, (data, error) in zip(full, runs):
            out.append(Results(header, data, error, [], mechanism=variant_mechanism(mech, row)))
            if len(out) == chunk:
                yield out
                out = []
        if out:
            yield out

    def write_csv(self, path: str | Path) -> int:
        """Write the run to a CSV file (atomic; .npz or .parquet by the suffix, any
        other refused); returns the rows written. The results of `solve()`, if it
        ran; else the run is streamed instant by instant."""
        if self.results is not None:
            return self.results.write_csv(path)
        return write_table(path, self.columns(), self.blocks(), self.analysis.steps)

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
            set_values: Mapping[str, str] | None = None, sensitivity: str | Sequence[str] | None = None,
            sensitivity_of: str | Sequence[str] | None = None, **analysis: Any) -> Study:
    """Load (if a path), lay out and build the evaluator of a mechanism.

    Args:
        mechanism: a `Mechanism` or the path of a mechanism file.
        backend: one of `symid.backends.names()`.
        set_values: parameter overrides (files only), name -> expression text.
        sensitivity: base parameters (a list, or "A,B"): adds the columns
            `d(COLUMN)/d(NAME)` (`symid solve --sensitivity`).
        sensitivity_of: the columns to differentiate (default: the drivers'
            effort columns and the reaction columns).
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
    from symid.output.sensitivity import choose

    layout = assemble(mech)
    needs = needs_of(mech)
    choice = None
    if sensitivity is not None or sensitivity_of is not None:
        from symid.backends.prepare import check

        check(mech, backend, layout)  # what the backend refuses is said before the sensitivities' names
        choice = choose(mech, layout, sensitivity, sensitivity_of, needs.reactions)
    if choice is not None:
        needs = dataclasses.replace(needs, sensitivity=choice.names, sensitivity_of=choice.of)
    solver = prepare_solver(mech, backend, needs, layout)
    return Study(mech, layout, solver.evaluator, solver.values, backend=backend, sensitivity=choice, solver=solver)


def load_mechanism(path: str | Path, set_values: Mapping[str, str] | None = None,
                   **analysis: Any) -> Mechanism:
    """Read and validate a mechanism file (see `symid.io.reader.load`)."""
    _known(analysis, "load_mechanism", ANALYSIS_KEYS + FILE_ONLY_KEYS)
    return load(path, set_values, analysis)


def generate(mechanism: Mechanism | str | Path, target: str, out_dir: str | Path,
             precision: str = "double", sensitivity: str | Sequence[str] | None = None,
             sensitivity_of: str | Sequence[str] | None = None, force: bool = False) -> list[Path]:
    """Write the generated code of one target ("c", "numpy", "casadi") into out_dir.

    What is emitted follows the mechanism's `[analysis]`: kind, outputs and reactions.
    precision: "double" or "single" (C only: the type of every floating value).
    sensitivity: base parameters (C only; a list or "A,B") whose derivatives
    `d(COLUMN)/d(NAME)` the rows end with, for the columns `sensitivity_of`
    (default: the drivers' efforts and the reactions); None: the code as without.
    The folder is written as a whole (`symid.io.folder`): every file or, on a
    fault, none; a file there that symid did not generate (or that changed
    since) is refused, naming it, unless `force`.
    """
    from symid.codegen import targets
    from symid.codegen.model import code_model
    from symid.io.folder import write_folder

    module = targets.get(target)
    mech = mechanism if isinstance(mechanism, Mechanism) else load(mechanism)
    require_square(mech)
    if sensitivity is not None or sensitivity_of is not None:
        model = _sensitivity_model(mech, target, sensitivity, sensitivity_of)
        return write_folder(out_dir, lambda folder: module.generate(model, folder, precision=precision), force)
    joint = friction.first_joint(mech)
    if joint is not None and target not in ("c", "fmu"):  # never generate a solver that silently ignores friction
        raise InputError(f"{mech.source}: constraint '{joint}' key 'friction': --target {target}: the generated "
                         f"{target} code does not include joint friction yet; generate --target c, or solve "
                         f"with any backend")
    if precision != "double":
        if target != "c":
            raise InputError(f"generate: precision {precision!r} applies to the c target only")
        looped = code_model(mech, looped=True)
        return write_folder(out_dir, lambda folder: module.generate(looped, folder, precision=precision), force)
    plain = code_model(mech, looped=target == "c")
    return write_folder(out_dir, lambda folder: module.generate(plain, folder), force)


def _sensitivity_model(mech: Mechanism, target: str, names: str | Sequence[str] | None,
                       of: str | Sequence[str] | None) -> Any:
    """The code model of `generate` with sensitivity columns (C only), checked and
    defaulted as `symid solve --sensitivity` checks them, before the derivation."""
    from symid.codegen.model import code_model, options_for
    from symid.output.sensitivity import choose

    if target != "c":
        raise InputError(f"generate: --sensitivity applies to --target c only (the {target} code has none yet)")
    options = options_for(mech)
    choice = choose(mech, assemble(mech), names, of, options.reactions)
    assert choice is not None  # names given (choose refuses --sensitivity-of alone)
    options = dataclasses.replace(options, sensitivity=choice.names, sensitivity_of=choice.of)
    return code_model(mech, options, looped=True)


def generate_examples(out_dir: str | Path, targets: tuple[str, ...] = ("c", "numpy", "casadi"),
                      force: bool = False) -> list[Path]:
    """Regenerate the committed `generated/<example>/<target>/` folders."""
    written = []
    for name in examples():
        mech = load(example(name))
        if friction.first_joint(mech) is not None:  # generated code has no joint friction yet
            continue
        for target in targets:
            written += generate(mech, target, Path(out_dir) / name / target, force=force)
    return written


def solve(mechanism: Mechanism | str | Path, backend: str = "numpy", sensitivity: str | Sequence[str] | None = None,
          sensitivity_of: str | Sequence[str] | None = None, **analysis: Any) -> Results:
    """Prepare and solve in one call; see `prepare` and `Study.solve`."""
    return prepare(mechanism, backend, sensitivity=sensitivity, sensitivity_of=sensitivity_of, **analysis).solve()


def sweep(mechanism: Mechanism | str | Path, variants: Any, backend: str = "c", workers: int | None = None,
          client: Any = None) -> Any:
    """The figures of many variants of one mechanism (`symid sweep`), as a `SweepTable`.

    Args:
        mechanism: a `Mechanism` or the path of a mechanism file.
        variants: a `symid.study.design.Variants` (e.g. `symid.study.design.grid(["L_rod=0.25:0.35:5"])`),
            or a mapping base parameter name -> K values (one variant per index).
        backend: "c" or "numpy" (also "casadi", "reference": variant by variant).
        workers: threads on this machine (None: all cores).
        client: a Dask `distributed.Client`: the chunks run on its cluster.

    Returns:
        the table: `columns`, `data`, `table[column]`, `write(path)`, `to_pandas()`.
    """
    from symid.study import run
    from symid.study import inertials
    from symid.study.design import Variants, check_count, check_names

    mech = mechanism if isinstance(mechanism, Mechanism) else load(mechanism)
    if not isinstance(variants, Variants):
        names = tuple(variants)
        columns = [np.asarray(variants[n], dtype=float).ravel() for n in names]
        if len({len(c) for c in columns}) > 1:
            raise ValueError(f"sweep(): the variants' columns differ in length: "
                             f"{', '.join(f'{n} {len(c)}' for n, c in zip(names, columns))}")
        variants = Variants("table", names, np.column_stack(columns) if columns else np.zeros((0, 0)))
    check_names(variants.names, mech.parameters, mech.source, "sweep")
    check_count(len(variants), "sweep")
    inertials.check(mech, variants.names, variants.values, "sweep")
    return run.solve(mech, variants, backend, workers, client)
