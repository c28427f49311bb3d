"""Run plans: a repeated `symid solve` that neither derives nor imports sympy.

Reading a file, laying it out and finding its cached solver costs about a
second of sympy before the first instant is solved. Yet everything a run
needs once its solver is built is a handful of numbers and names: the
solver's location, the parameter vector, q0, the analysis grid, the columns,
and for the summary lines each driver's f and f' at the output instants.
After a successful run the command line keeps these as a plan; a later run
with the same inputs loads the plan and streams the table through the same
writer, with the same evaluator class and row loop, as the normal path.

The key hashes every input of a run as bytes: the mechanism file and every
table it may read, the command-line options that change the run, the file's
name and the current folder (relative table paths resolve against them),
and symid's own code (`symid.codegen.sources.code_version`). Anything unreadable,
missing, corrupt or inconsistent means no plan: the normal path runs, and
answers are never taken from a stale plan. Only successful runs leave a
plan; a planned run that fails discards its output and its plan and reruns
the normal path, which reports the failure with the layout's names.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Mapping, Sequence, cast

import numpy as np

from symid import backends
from symid.model.analysis import Analysis
from symid.backends import Array, Evaluator
from symid.errors import SymidError
from symid.io.files import read_at_most
from symid.io.limits import MAX_FILE_BYTES
from symid.output.results import table_blocks
from symid.codegen.sources import code_version
from symid.numeric.stability import Notes
from symid.output.summary import Input, Source

if TYPE_CHECKING:
    from symid.api import Study

FORMAT = 2  # 2: sealed by the sha256 of its body
# Each driver's f and f' are kept per output instant; past this many instants
# the solve itself dominates and a plan would only be a large file.
MAX_INSTANTS = 100_000


class Stale(Exception):
    """A planned run failed: nothing was written and the normal path must run.

    Deliberately not a `SymidError`: it never reaches the user.
    """


def folder() -> Path:
    """Where plans are kept: `plans/` in the solver cache in use (`symid.codegen.cache.root`)."""
    from symid.codegen.cache import root

    return root() / "plans"


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def key(file: str, options: Mapping[str, Any]) -> str | None:
    """The plan key of `symid solve file` with these options, or None when
    the file cannot be read or parsed (the normal path reports why).

    Args:
        file: the mechanism file as given on the command line.
        options: every command-line option that changes the run (JSON values).
    """
    path = Path(file)
    try:
        data = read_at_most(path, MAX_FILE_BYTES)
        if len(data) > MAX_FILE_BYTES:  # (a device or endless stream: the normal path says so)
            return None
        document = tomllib.loads(data.decode("utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError):
        return None
    from symid.io.paths import referenced_tables

    tables: list[list[str | None]] = []  # [path, digest or None if unreadable]
    for table in referenced_tables(document, str(path)):
        try:
            content = read_at_most(table, MAX_FILE_BYTES)
            tables.append([str(table), _digest(content) if len(content) <= MAX_FILE_BYTES else None])
        except OSError:
            tables.append([str(table), None])
    inputs = [FORMAT, code_version(), os.getcwd(), file, _digest(data), tables, dict(options)]
    return _digest(json.dumps(inputs, sort_keys=True).encode())[:32]


@dataclass(frozen=True)
class Plan:
    """What a run needs once its solver is built.

    Attributes:
        backend: its name; artifact: the backend's built solver (a path).
        name: the mechanism's name; params: parameter name -> value.
        q0: the initial guess, size ng; analysis: the run's analysis.
        columns: the table header; keep: the columns the summary reads.
        summary: each driver's summary inputs (`symid.output.summary.Input`).
    """

    backend: str
    artifact: str
    name: str
    params: Mapping[str, float]
    q0: Sequence[float]
    analysis: Analysis
    columns: list[str]
    keep: list[str]
    summary: list[Input]

    def evaluator(self) -> Evaluator:
        """The backend's evaluator over the built solver (raises if it is gone)."""
        backend = backends.get(self.backend)
        if not backend.capabilities.loads:  # a plan is made only for one that loads (`of`)
            raise ValueError(f"the {self.backend} backend loads no built solver")
        return cast(backends.Loader, backend).load(Path(self.artifact), self.name, self.params)

    def rows(self, evaluator: Evaluator, notes: Notes) -> Iterator[Array]:
        """The table as rows or blocks, as `Study.blocks`; any failure raises `Stale`.

        Not only `AnalysisError`: the evaluator has no layout (it names the
        constraints of a failure), so its diagnosis may fail otherwise; the
        normal path reruns and reports the failure either way.
        """
        try:
            yield from table_blocks(evaluator, self.analysis, np.array(self.q0, dtype=float), notes)
        except Exception:  # noqa: BLE001
            raise Stale() from None

    def to_json(self) -> str:
        summary = [{"source": None if i.source is None else dataclasses.asdict(i.source), "missing": i.missing,
                    "t": i.t.tolist(), "f": i.f.tolist(), "fd": i.fd.tolist()} for i in self.summary]
        data = {"format": FORMAT, "backend": self.backend, "artifact": self.artifact, "name": self.name,
                "params": dict(self.params), "q0": list(self.q0), "analysis": dataclasses.asdict(self.analysis),
                "columns": self.columns, "keep": self.keep, "summary": summary}
        # sealed like every cache entry: a plan damaged into other valid JSON
        # (a digit of a parameter) would otherwise give other numbers, exit 0
        return json.dumps({**data, "sha256": _digest(json.dumps(data, sort_keys=True).encode())})

    @classmethod
    def from_json(cls, text: str) -> Plan:
        """Raises ValueError, KeyError or TypeError on anything unexpected."""
        data = json.loads(text)
        recorded = data.pop("sha256", None)
        if recorded != _digest(json.dumps(data, sort_keys=True).encode()):  # JSON floats round-trip exactly
            raise ValueError("the plan does not match its recorded sha256 (damaged)")
        if data.get("format") != FORMAT:
            raise ValueError("another plan format")
        analysis = dict(data["analysis"])
        for name in ("outputs", "reactions"):
            if analysis[name] is not None:
                analysis[name] = tuple(analysis[name])
        summary = [Input(None if s["source"] is None else Source(**s["source"]), s["missing"],
                         *(np.array(s[k], dtype=float) for k in ("t", "f", "fd"))) for s in data["summary"]]
        return cls(str(data["backend"]), str(data["artifact"]), str(data["name"]),
                   {str(k): float(v) for k, v in data["params"].items()}, [float(v) for v in data["q0"]],
                   Analysis(**analysis), [str(c) for c in data["columns"]], [str(c) for c in data["keep"]],
                   summary)


def load(plan_key: str) -> tuple[Plan, Evaluator] | None:
    """The plan stored under `plan_key` and its evaluator, or None (no plan,
    a corrupt one, or a solver no longer there)."""
    from symid.codegen.cache import distrust

    try:
        where = folder()
        if distrust(where) is not None:  # a plan names the code to load: only from a private folder
            return None
        fd = os.open(where / f"{plan_key}.json", os.O_RDONLY | os.O_NOFOLLOW)
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(fd)
            if st.st_uid != os.geteuid() or st.st_mode & 0o022:
                return None
            plan = Plan.from_json(f.read().decode("utf-8"))
        return plan, plan.evaluator()  # the backend checks its solver (`symid.codegen.cache.loadable`)
    except Exception:  # noqa: BLE001 (any doubt about a cache entry: the normal path decides)
        return None


def discard(plan_key: str) -> None:
    (folder() / f"{plan_key}.json").unlink(missing_ok=True)


def of(study: Study, backend_name: str, columns: list[str], keep: list[str], summary: list[Input]) -> Plan | None:
    """The plan of a study that ran successfully, or None when its run cannot be
    replayed without sympy (a backend without built artifacts, redundant rows
    named in a warning, or too many instants), or warned about its input
    (`symid.io.misreading`: a replay would not read the file, so not repeat them)."""
    if study.notes is not None and study.notes.fixed:
        return None
    if study.evaluator.friction is not None:  # its model is lambdified from sympy
        return None
    if not study.evaluator.capabilities.loads:  # nothing built to load again
        return None
    artifact = study.evaluator.artifact  # type: ignore[attr-defined]
    if study.layout.nc != study.layout.ng or study.analysis.steps > MAX_INSTANTS:
        return None
    params = {symbol.name: float(value) for symbol, value in study.values.items()}
    return Plan(backend_name, str(artifact), study.mechanism.name, params, study.q0().tolist(), study.analysis,
                columns, keep, summary)


def store(plan_key: str, plan: Plan) -> None:
    """Write a plan atomically; a cache that cannot be written is only slower."""
    from symid.codegen.cache import make_private_dirs

    try:
        where = folder()
        make_private_dirs(where)
        fd, tmp = tempfile.mkstemp(prefix=f".{plan_key}.", suffix=".tmp", dir=where)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as out:
                out.write(plan.to_json())
            os.replace(tmp, where / f"{plan_key}.json")
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except (OSError, SymidError):
        pass
