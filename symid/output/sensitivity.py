"""`--sensitivity` / `--sensitivity-of`: which columns, their names, and the rows.

Contract v1.1: after all other columns, `d(COLUMN)/d(NAME)` for every chosen
column (default: the drivers' effort columns and the reaction columns) and
every named base parameter, columns outer, parameters inner. Every backend
solves through the shared Python loop (`symid.numeric.solve.run`), whose
factorization of Phi_q each instant's sensitivities reuse.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator, Mapping, Sequence

import numpy as np

from symid.errors import InputError
from symid.model.analysis import Analysis
from symid.model.friction import has_friction
from symid.model.params import base_names, is_derived
from symid.numeric.solve import instant_row, run
from symid.output.results import table_rows
from symid.numeric.stability import Factor, Notes, Scaling
from symid.output.summary import drivers, source
from symid.symbolic.columns import GROUP_SUFFIXES, columns

if TYPE_CHECKING:
    from symid.backends import Array, Evaluator
    from symid.model.mechanism import Mechanism
    from symid.numeric.sensitivity import SensitivityEvaluator, Stacked
    from symid.symbolic.assemble import Layout

# The table groups a column can be differentiated in, and where each group's
# derivatives are in `Derivatives`.
CHUNK = 128  # instants whose sensitivities are evaluated at once (numpy's per-call cost, shared)
_GROUPS = {"q": "q", "qdot": "qd", "qddot": "qdd", "lambda": "lam", "reactions": "reactions"}


@dataclass(frozen=True)
class Choice:
    """The sensitivity columns of one run.

    Attributes:
        names: base parameters (inner order); of: the differentiated columns (outer).
        where: per column of `of`, (attribute of `Derivatives`, row in it).
        reactions: the constraints whose reactions the table has.
    """

    names: tuple[str, ...]
    of: tuple[str, ...]
    where: tuple[tuple[str, int], ...]
    reactions: tuple[str, ...] = ()  # the constraints whose reactions the table has (file order)

    @property
    def header(self) -> list[str]:
        return [f"d({c})/d({n})" for c in self.of for n in self.names]


def _split(values: str | Sequence[str] | None, option: str, source_name: str) -> tuple[str, ...] | None:
    """A list option: "A,B" or ["A", "B"]; None when not given. Empty, blank or repeated items are errors."""
    if values is None:
        return None
    items = [v.strip() for v in (values.split(",") if isinstance(values, str) else
                                 [x for v in values for x in str(v).split(",")])]
    if not items or any(not v for v in items):
        raise InputError(f"{source_name}: {option}: an empty name in the list {','.join(items)!r} "
                         f"(give NAME[,NAME...])")
    seen: set[str] = set()
    for item in items:
        if item in seen:
            raise InputError(f"{source_name}: {option}: {item!r} is named twice")
        seen.add(item)
    return tuple(items)


def _where(layout: Layout, analysis: Analysis, reaction_count: int) -> dict[str, tuple[str, int]]:
    """Every column a sensitivity can be taken of -> (Derivatives attribute, row)."""
    header = columns(layout, analysis)
    sizes = {"q": layout.ng, "qdot": layout.ng, "qddot": layout.ng, "lambda": layout.nc,
             "reactions": reaction_count}
    out: dict[str, tuple[str, int]] = {}
    at = 1
    for group in analysis.output_groups():
        if group not in sizes:
            continue
        for k in range(sizes[group]):
            out[header[at + k]] = (_GROUPS[group], k)
        at += sizes[group]
    if analysis.kind == "inverse_dynamics" and "reactions" in analysis.output_groups():
        joints = [c.name for c in layout.mechanism.constraints if has_friction(c)]  # after every other column
        for k, name in enumerate(joints):
            out[f"{name}.friction"], out[f"{name}.friction_power"] = ("friction", 2 * k), ("friction", 2 * k + 1)
    return out


def choose(mechanism: Mechanism, layout: Layout, names: str | Sequence[str] | None,
           of: str | Sequence[str] | None, reactions: tuple[str, ...]) -> Choice | None:
    """Check `--sensitivity NAMES` and `--sensitivity-of COLUMNS`; None without NAMES.

    Raises:
        InputError: an empty list, a repeated name, an unknown or derived
            parameter (naming its definition), an unknown column, a kind that
            has none of the default columns.
    """
    where_ = mechanism.source
    chosen = _split(names, "--sensitivity", where_)
    wanted = _split(of, "--sensitivity-of", where_)
    if chosen is None:
        if wanted is not None:
            raise InputError(f"{where_}: --sensitivity-of: needs --sensitivity NAME[,NAME...] (the parameters)")
        return None
    params = mechanism.parameters
    base = base_names(params)
    for name in chosen:
        if name not in params:
            raise InputError(f"{where_}: --sensitivity {name}: no such parameter (base parameters: "
                             f"{', '.join(base) or 'none'})")
        if is_derived(params[name]):
            uses = ", ".join(sorted(str(x) for x in params[name].free_symbols))
            raise InputError(f"{where_}: --sensitivity {name}: '{name}' is a derived parameter ({name} = "
                             f"\"{params[name]}\" in [parameters]); take the sensitivity to the base parameters "
                             f"it is computed from ({uses})")
    analysis = mechanism.analysis
    where = _where(layout, analysis, reaction_count(reactions, mechanism))
    if wanted is None:
        header = columns(layout, analysis)
        efforts = {s.column for s in (source(c, header) for c in drivers(mechanism)) if s is not None}
        wanted = tuple(c for c in where if c in efforts or where[c][0] == "reactions")
        if not wanted:
            raise InputError(f"{where_}: --sensitivity: a {analysis.kind} table without lambda or reactions has "
                             f"no effort or reaction columns to differentiate; name columns with --sensitivity-of")
    for column in wanted:
        if column not in where:
            known = ", ".join(list(where)[:8]) + (", ..." if len(where) > 8 else "")
            raise InputError(f"{where_}: --sensitivity-of {column}: no such column in this table "
                             f"(columns: {known or 'none'})")
    return Choice(chosen, wanted, tuple(where[c] for c in wanted), reactions)


def rows(evaluator: Evaluator, analysis: Analysis, q0: Array, notes: Notes, choice: Choice,
         sens: SensitivityEvaluator, chunk: int = CHUNK) -> Iterator[Array]:
    """The table with the sensitivity columns appended, in blocks of `chunk`
    rows whose sensitivities are computed at once, vectorized over the
    instants (a failure still yields every instant solved before it).

    A backend with its own loop (numpy's generated one, several times the
    shared Python loop's speed) solves when its rows hold what the
    sensitivities start from (q, and qdot, qddot, lambda where needed):
    Phi_q is then factored again per instant. Otherwise the shared Python
    loop, whose factorization each instant's sensitivities reuse."""
    want_lam = any(attr in ("lam", "reactions", "friction") for attr, _ in choice.where)
    want_r = any(attr == "reactions" for attr, _ in choice.where)
    ng = len(q0)
    dyn = analysis.kind != "statics"
    at = _starts(sens.layout, analysis)
    need = ["q"] + (["qdot", "qddot"] if dyn else []) + (["lambda"] if want_lam else [])
    own = evaluator.capabilities.own_loop and all(g in at for g in need)
    held: list[tuple[Array, Array, Factor | None]] = []  # (row, state: t, q[, qd, qdd][, lam], factor)
    scaling: list[Scaling] = []  # a backend's own loop: one equilibration for the run (t0's), as the loop's

    def flush() -> Iterator[Array]:
        state = np.array([h[1] for h in held])
        ts, q = state[:, 0], state[:, 1:1 + ng]
        qd = state[:, 1 + ng:1 + 2 * ng] if dyn else None
        qdd = state[:, 1 + 2 * ng:1 + 3 * ng] if dyn else None
        lam = state[:, 1 + (3 if dyn else 1) * ng:] if want_lam else None
        factors = _factors(evaluator, [h[2] for h in held], q, ts, scaling)
        d = sens.chunk(factors, ts, q, qd, qdd, lam, want_r)
        table = np.array([h[0] for h in held])
        yield np.hstack([table, *(getattr(d, attr)[row] for attr, row in choice.where)])  # one block of rows
        held.clear()

    def state(row: Array) -> Array:
        return np.concatenate([row[:1], *(row[at[g]:at[g] + (ng if g != "lambda" else sens.layout.nc)]
                                          for g in need)])

    def solved() -> Iterator[tuple[Array, Array, Factor | None]]:
        if own:
            for row in table_rows(evaluator, analysis, q0, notes):
                yield row, state(row), None
            return
        for item in run(evaluator, analysis, q0, notes):
            parts = [item.t, item.q, *([item.qd, item.qdd] if dyn else []), *([item.lam] if want_lam else [])]
            yield instant_row(item, ng, analysis), np.hstack(parts), item.factor  # type: ignore[arg-type]

    try:
        for one in solved():
            held.append(one)
            if len(held) >= chunk:
                yield from flush()
    except Exception:  # a failed instant: the ones solved before it first
        if held:
            yield from flush()
        raise
    if held:
        yield from flush()


def _starts(layout: Layout, analysis: Analysis) -> dict[str, int]:
    """The first column of each of the table's q, qdot, qddot, lambda groups."""
    sizes = {"q": layout.ng, "qdot": layout.ng, "qddot": layout.ng, "lambda": layout.nc}
    out, at = {}, 1
    for group in analysis.output_groups():
        if group in sizes:  # reactions come last (OUTPUT_GROUPS order)
            out[group] = at
            at += sizes[group]
    return out


def _factors(evaluator: Evaluator, kept: list[Factor | None], q: Array, ts: Array,
             scaling: list[Scaling]) -> list[Factor] | Stacked:
    """The instants' factorizations of Phi_q: the loop's, or (a backend's own
    loop keeps none) Phi_q again, under the run's one scaling (made at the
    first instant: `scaling` keeps it), stacked when square."""
    if all(f is not None for f in kept):
        return kept  # type: ignore[return-value]
    jac = np.array([evaluator.phi_q(q[k], ts[k]) for k in range(len(kept))])
    if not scaling:
        scaling.append(Scaling.of(jac[0], q[0]))
    if jac.shape[1] == jac.shape[2]:
        from symid.numeric.sensitivity import Stacked

        return Stacked(jac, scaling[0])
    return [Factor(j, scaling[0]) for j in jac]


def reaction_count(reactions: tuple[str, ...], mechanism: Mechanism) -> int:
    """How many reaction columns the chosen constraints have."""
    return mechanism.reaction_starts(set(reactions))[1]


def evaluator_for(layout: Layout, values_: Mapping, choice: Choice, analysis: Analysis) -> SensitivityEvaluator:
    """The sensitivity evaluator of a run (derives on first use)."""
    from symid.numeric.sensitivity import SensitivityEvaluator

    return SensitivityEvaluator(layout, values_, choice.names, analysis.kind == "statics", choice.reactions)
