"""Check hand derivations ("claims") against symid's own derivation.

A claim file (TOML, `docs/claims.md`) names a constraint type or a mechanism
file and gives expressions for Phi, Phi_q blocks, nu, gamma, reactions, Q^A or
M. Each entry is proved equal symbolically, or, when simplification is
inconclusive, tested at seeded random points; a failing entry gets the
simplified difference and an exact counterexample point.

    >>> report = verify("symid/claims/revolute.toml")
    >>> report.ok, report.exit_status
"""

from __future__ import annotations

import dataclasses
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, Mapping, Protocol, cast

import sympy as sp

from symid.errors import InputError
from symid.io.files import read_text
from symid.model.expr import parse_expression
from symid.tools.show import tidy
from symid.tools.subjects import MechanismSubject, Points, TypeSubject, evaluate, random_points

TOL = 1e-9  # relative tolerance of a numeric comparison (exact points, 30 digits)
TOP = ("claim", "define", "entry")
ENTRY = ("quantity", "value", "body", "constraint", "condition", "note")


class Subject(Protocol):
    """What a claim is about: a constraint type or a whole mechanism."""

    label: str

    def names(self) -> dict[str, sp.Expr]: ...

    def quantity(self, qty: Any, body: Any, constraint: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]: ...

    def consistent(self) -> tuple[dict[sp.Symbol, sp.Expr], str, Points]: ...


def bundled() -> list[Path]:
    """The claim files shipped with symid (the lecture notes' hand results)."""
    folder = resources.files("symid") / "claims"
    return sorted(Path(str(p)) for p in folder.iterdir() if p.name.endswith(".toml"))


@dataclasses.dataclass(frozen=True)
class Outcome:
    """The verdict on one entry.

    Attributes:
        index: 1-based entry number; label: quantity, body, constraint.
        condition: "general", or what "consistent" / a custom condition substituted.
        method: "symbolic" or how the numeric test was done.
        difference: derived - claimed, simplified (None when equal).
        wrong: the (row, column) elements that differ.
        point: symbol name -> value of a counterexample, in the claim's symbols.
        derived_at, claimed_at: the two sides at `point`, as floats (row by row).
        note: the entry's own `note`, shown with a failure.
    """

    index: int
    label: str
    condition: str
    equal: bool
    method: str
    difference: sp.Matrix | None = None
    wrong: tuple[tuple[int, int], ...] = ()
    point: Mapping[str, sp.Expr] | None = None
    derived_at: tuple[float, ...] = ()
    claimed_at: tuple[float, ...] = ()
    note: str = ""

    def text(self) -> str:
        cond = "" if self.condition == "general" else f" [{self.condition}]"
        head = f"  #{self.index} {self.label}{cond}: "
        if self.equal:
            return head + f"equal ({self.method})"
        lines = [head + f"NOT EQUAL ({self.method})"] + ([f"      claim: {self.note}"] if self.note else [])
        difference = cast(sp.Matrix, self.difference)  # set whenever `wrong` is (compare)
        for r, c in self.wrong:
            lines.append(f"      element [{r + 1}, {c + 1}]: derived - claimed = {sp.sstr(difference[r, c])}")
        if self.point is not None:
            shown = (f"{k} = {float(v):.17g}" if isinstance(v, sp.Float) else f"{k} = {v}" for k, v in self.point.items())
            # no symbols left (a mechanism's parameters stand for their values): it fails everywhere
            lines.append("      counterexample: " + (", ".join(shown) or "any values (the claim has no free symbols)"))
            lines.append(f"      there derived = {_nums(self.derived_at)}, claimed = {_nums(self.claimed_at)}")
        return "\n".join(lines)


def _nums(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{v:.10g}" for v in values) + "]"


@dataclasses.dataclass(frozen=True)
class Report:
    """The verdicts on every entry of one claim file."""

    source: str
    subject: str
    outcomes: tuple[Outcome, ...]

    @property
    def ok(self) -> bool:
        return all(o.equal for o in self.outcomes)

    @property
    def exit_status(self) -> int:
        return 0 if self.ok else 1

    def text(self) -> str:
        bad = sum(not o.equal for o in self.outcomes)
        n = len(self.outcomes)
        verdict = (("the entry holds" if n == 1 else f"all {n} entries hold") if not bad
                   else f"{bad} of {n} entries {'does' if bad == 1 else 'do'} not hold")
        return "\n".join([f"{self.source}: {self.subject}", *(o.text() for o in self.outcomes), verdict])

    def __repr__(self) -> str:
        bad = sum(not o.equal for o in self.outcomes)
        return (f"Report({self.source}: {self.subject}; {len(self.outcomes)} entries, "
                f"{'all hold' if not bad else f'{bad} do not hold'})")

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(self.text())}</pre>"


def verify(path: str | Path) -> Report:
    """Verify one claim file. Raises InputError (exit status 2) when it is malformed."""
    path = Path(path)
    return verify_text(read_text(path), str(path), path.parent)


def verify_text(text: str, source: str = "<claims>", folder: Path | None = None) -> Report:
    """Verify claim-file text; `source` names it in messages, `folder` resolves `mechanism`."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: TOML syntax error: {exc}") from None
    return _Checker(source, folder or Path(".")).run(data)


class _Checker:
    def __init__(self, source: str, folder: Path) -> None:
        self.source, self.folder = source, folder

    def fail(self, where: str, message: str) -> InputError:
        return InputError(f"{self.source}: {where}: {message}")

    def table(self, value: Any, where: str, allowed: tuple[str, ...] | None = None) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, "must be a table")
        extra = [k for k in value if allowed is not None and k not in allowed]
        if extra:
            raise self.fail(f"{where} key '{extra[0]}'", f"unknown key (allowed: {', '.join(allowed or ())})")
        return value

    def run(self, data: dict[str, Any]) -> Report:
        self.table(data, "top level", TOP)
        head = self.table(data.get("claim"), "[claim]", ("type", "mechanism", "options", "title", "condition"))
        subject = self.subject(head)
        names = self.define(self.table(data.get("define", {}), "[define]"), subject)
        entries = data.get("entry")
        if not isinstance(entries, list) or not entries:
            raise self.fail("top level", "no [[entry]]: a claim file needs at least one entry")
        default = head.get("condition", "general")
        outcomes = [self.entry(n + 1, e, subject, names, default) for n, e in enumerate(entries)]
        title = f" ({head['title']})" if isinstance(head.get("title"), str) else ""
        return Report(self.source, subject.label + title, tuple(outcomes))

    def subject(self, head: dict[str, Any]) -> Subject:
        if ("type" in head) == ("mechanism" in head):
            raise self.fail("[claim]", "give exactly one of 'type' and 'mechanism'")
        options = self.table(head.get("options", {}), "[claim] key 'options'")
        if "type" in head:
            try:
                return TypeSubject(str(head["type"]), {k: str(v) for k, v in options.items()})
            except InputError as exc:
                raise self.fail("[claim] key 'type'", str(exc)) from None
        raw = head["mechanism"]
        if not isinstance(raw, str):
            raise self.fail("[claim] key 'mechanism'", "must be a path string")
        path = self.folder / raw
        if not path.is_file():
            from symid import api

            if raw in api.examples():
                path = api.example(raw)
        return MechanismSubject(path)

    def define(self, table: dict[str, Any], subject: Subject) -> dict[str, sp.Expr]:
        names = dict(subject.names())
        for name, raw in table.items():
            where = f"[define] key '{name}'"
            if (name in names and name not in DISPLAY_NAMES) or not name.isidentifier() or name.startswith("_"):
                raise self.fail(where, "is a name of the symbol table or not a valid name")
            if isinstance(raw, list):
                if len(raw) != 2:
                    raise self.fail(where, "a vector has two components (defines NAME_x, NAME_y)")
                for comp, value in zip("xy", raw):
                    names[f"{name}_{comp}"] = self.expr(value, where, names)
            else:
                names[name] = self.expr(raw, where, names)
        return names

    def expr(self, raw: Any, where: str, names: Mapping[str, sp.Expr]) -> sp.Expr:
        return parse_expression(raw, names, f"{self.source}: {where}", functions=_functions(names, where))

    def entry(self, index: int, raw: Any, subject: Subject, names: Mapping[str, sp.Expr],
              default: Any) -> Outcome:
        where = f"entry #{index}"
        raw = self.table(raw, where, ENTRY)
        for key in ("quantity", "value"):
            if key not in raw:
                raise self.fail(where, f"missing key '{key}'")
        try:
            label, derived, keys = subject.quantity(raw["quantity"], raw.get("body"), raw.get("constraint"))
        except InputError as exc:
            raise self.fail(where, str(exc)) from None
        value = raw["value"]
        if isinstance(value, dict) and keys is not None:  # named blocks: only those given
            unknown = [k for k in value if k not in keys] or ([""] if not value else [])
            if unknown:
                raise self.fail(f"{where} key 'value'", f"unknown block {unknown[0]!r} (blocks: {', '.join(keys)})")
            derived = sp.Matrix.hstack(*(derived[:, 3 * n:3 * n + 3] for n, k in enumerate(keys) if k in value))
            claimed = sp.Matrix.hstack(*(self.value(value[k], (derived.rows, 3), f"{where} key 'value.{k}'", names)
                                         for k in keys if k in value))
        else:
            claimed = self.value(value, derived.shape, f"{where} key 'value'", names)
        subs, cond_text, points = self.condition(raw.get("condition", default), subject, names,
                                                 f"{where} key 'condition'")
        note = raw.get("note", "")
        if not isinstance(note, str):
            raise self.fail(f"{where} key 'note'", "must be a string")
        return dataclasses.replace(compare(index, label, derived, claimed, subs, cond_text, points), note=note)

    def condition(self, cond: Any, subject: Subject, names: Mapping[str, sp.Expr],
                  where: str) -> tuple[dict[sp.Symbol, sp.Expr], str, Points]:
        """Substitution, its description and the numeric test points of a condition."""
        if cond == "general":
            return {}, "general", random_points()
        if cond == "consistent":
            return subject.consistent()
        if not isinstance(cond, dict):
            raise self.fail(where, "must be 'general', 'consistent' or a table "
                            "{ substitute = { NAME = EXPR, ... }, positive = [NAMES] }")
        cond = self.table(cond, where, ("substitute", "positive"))
        new = cond.get("positive", [])
        if not isinstance(new, list) or not all(isinstance(n, str) and n.isidentifier() for n in new):
            raise self.fail(f"{where} key 'positive'", "must be a list of new names")
        local = {**names, **{n: sp.Symbol(n, positive=True) for n in new}}
        subs = {}
        for name, value in self.table(cond.get("substitute", {}), f"{where} key 'substitute'").items():
            if not isinstance(names.get(name), sp.Symbol):
                raise self.fail(f"{where} key 'substitute'", f"{name!r} is not a symbol of the symbol table")
            subs[names[name]] = self.expr(value, f"{where} key 'substitute.{name}'", local)
        return subs, "where " + ", ".join(f"{k} = {sp.sstr(v)}" for k, v in subs.items()), random_points()

    def value(self, raw: Any, shape: tuple[int, int], where: str, names: Mapping[str, sp.Expr]) -> sp.Matrix:
        """A scalar, a list (a row or a column) or a list of rows, of the given shape."""
        rows, cols = shape
        if not isinstance(raw, list):
            raw = [raw]
        if all(isinstance(r, list) for r in raw) and raw:
            grid = raw
        elif rows == 1 or cols == 1:
            grid = [raw] if rows == 1 else [[v] for v in raw]
        else:
            grid = [raw]
        if len(grid) != rows or any(not isinstance(r, list) or len(r) != cols for r in grid):
            got = f"{len(grid)} x {len(grid[0]) if grid and isinstance(grid[0], list) else '?'}"
            raise self.fail(where, f"expected {rows} x {cols} (rows x columns), got {got}")
        return sp.Matrix([[self.expr(v, where, names) for v in r] for r in grid])


def _functions(names: Mapping[str, sp.Expr], where: str) -> dict[str, Any]:
    """f(t), fd(t), fdd(t) as the driver symbols, and norm(x, y)."""
    out: dict[str, Any] = {"norm": (2, lambda x, y: sp.sqrt(x ** 2 + y ** 2))}
    t = names.get("t")
    for name in ("f", "fd", "fdd"):
        if name in names:
            def call(arg: sp.Expr, value: sp.Expr = names[name], name: str = name) -> sp.Expr:
                if arg != t:
                    raise InputError(f"{where}: {name}() is a function of t only: write {name}(t)")
                return value
            out[name] = (1, call)
    return out


def _simplified(e: sp.Expr) -> sp.Expr:
    e = tidy(e)
    if e != 0 and sp.count_ops(e) < 3000:
        e = sp.simplify(e)
    return e


def compare(index: int, label: str, derived: sp.Matrix, claimed: sp.Matrix, subs: Mapping[sp.Symbol, sp.Expr],
            condition: str, points: Points) -> Outcome:
    """Prove derived == claimed after `subs`, else test both at `points` (in the
    claim's own symbols, so a counterexample is a valid point of the claim)."""
    simple = (derived - claimed).xreplace(dict(subs)).applyfunc(_simplified)
    if all(e == 0 for e in simple):
        return Outcome(index, label, condition, True, "symbolic")
    free = sorted(derived.free_symbols | claimed.free_symbols, key=str)
    method = "numeric"
    for point, method in points(free, subs):
        d_at, c_at = (evaluate(m, point) for m in (derived, claimed))
        bad = tuple((r, c) for r in range(simple.rows) for c in range(simple.cols)
                    if abs(d_at[r, c] - c_at[r, c]) > TOL * (1 + abs(d_at[r, c]) + abs(c_at[r, c])))
        if bad:
            keep = set(free).union(*(v.free_symbols for v in subs.values()))
            shown = {str(k): v for k, v in point.items() if k in keep}
            real = lambda m: tuple(float(complex(v).real) for v in m)  # noqa: E731
            return Outcome(index, label, condition, False, method, simple, bad, shown, real(d_at), real(c_at))
    return Outcome(index, label, condition, True, method)


# -- what a claim can name -----------------------------------------------------------


# derive's hand notation as claim names; a [define] of the same name replaces it
DISPLAY_NAMES = frozenset({"dx", "dy", "dxd", "dyd"} | {f"{v}_{r}{c}" for v in "sa" for r in "ij" for c in "xy"})


