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
import random
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Protocol, cast

import sympy as sp

from symid import symbols as s
from symid.backends import Array
from symid.constraints import TYPES as CONSTRAINTS
from symid.derive import DerivedConstraint, derive_constraint
from symid.elements import registry_lookup
from symid.errors import InputError
from symid.expr import parse_expression
from symid.io.files import read_at_most
from symid.io.reader import MAX_FILE_BYTES
from symid.model import parameter_symbol
from symid.show import mechanism_system, tidy

POINTS = 24  # random points of a numeric test
TOL = 1e-9  # relative tolerance of a numeric comparison (exact points, 30 digits)
TOP = ("claim", "define", "entry")
ENTRY = ("quantity", "value", "body", "constraint", "condition", "note")

# A condition's test points: (free symbols, substitution) -> (point, method) pairs.
Points = Callable[[list[sp.Symbol], Mapping[sp.Symbol, sp.Expr]], Iterator[tuple[dict[sp.Symbol, sp.Expr], str]]]


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
            lines.append("      counterexample: " + ", ".join(shown))
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
    try:
        data = read_at_most(path, MAX_FILE_BYTES)
        if len(data) > MAX_FILE_BYTES:  # a device or endless stream is not read past the limit
            raise InputError(f"{path}: file is longer than the {MAX_FILE_BYTES} bytes allowed")
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    return verify_text(text, str(path), path.parent)


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


def random_points(seed: int = 2024) -> Points:
    """Seeded exact points: nonzero multiples of 1/8 in [-2, 2] (positive where assumed)
    for the free symbols; symbols a condition substitutes take their values from it."""
    def points(free: list[sp.Symbol], subs: Mapping[sp.Symbol, sp.Expr]) -> Iterator[tuple[dict, str]]:
        rng = random.Random(seed)
        used = set(free) - set(subs)
        base = sorted(used.union(*(v.free_symbols for k, v in subs.items() if k in free)), key=str)
        for _ in range(POINTS):
            point = {x: sp.Rational(rng.randint(1, 16), 8) * (1 if x.is_positive else rng.choice((-1, 1)))
                     for x in base}
            point.update({k: v.xreplace(point) for k, v in subs.items() if k in free})
            yield point, f"numeric, {POINTS} seeded random points"
    return points


def evaluate(m: sp.Matrix, point: Mapping[sp.Symbol, sp.Expr]) -> sp.Matrix:
    """`m` at `point`, 30 significant digits (complex where a root goes negative)."""
    return m.xreplace(dict(point)).applyfunc(lambda e: complex(sp.N(e, 30)))


# -- what a claim can name -----------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class View:
    """What entries of one subject may name.

    whole: Phi, nu, gamma (and Q_A, M of a mechanism); blocks: body -> its
    columns of Phi_q; reactions: role -> [Fx, Fy, T]; per_body: body -> its
    Q_A (3) and M (3 x 3).
    """

    whole: Mapping[str, sp.Matrix]
    blocks: Mapping[str, sp.Matrix]
    reactions: Mapping[str, sp.Matrix] = dataclasses.field(default_factory=dict)
    per_body: Mapping[str, Mapping[str, sp.Matrix]] = dataclasses.field(default_factory=dict)

    def pick(self, qty: Any, body: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]:
        """(label, derived matrix, the block names a named-block value may use)."""
        if qty in ("F_on", "T_on"):
            qty, body = f"{qty}_{body}", None
        label = qty if body is None else f"{qty}, body {body}"
        if isinstance(qty, str) and qty[1:5] == "_on_" and qty[0] in "FT" and qty[5:] in self.reactions:
            if body is not None:
                raise InputError(f"key 'body': {qty} names its body already")
            force = self.reactions[qty[5:]]
            return label, force[:2, :] if qty[0] == "F" else force[2:, :], None
        split = {"Phi_q": self.blocks, "Phi_r": self.blocks, "Phi_phi": self.blocks,
                 **{k: self.per_body for k in ("Q_A", "M") if self.per_body}}
        if qty not in split and qty not in self.whole:
            valid = [*self.whole, *(k for k in split if k not in self.whole),
                     *(f"{c}_on_{r}" for r in self.reactions for c in "FT")]
            raise InputError(f"key 'quantity': unknown quantity {qty!r} (valid: {', '.join(valid)})")
        if body is None:
            if qty == "Phi_q":
                return label, sp.Matrix.hstack(*self.blocks.values()), tuple(self.blocks)
            if qty not in self.whole:
                raise InputError(f"key 'body': {qty} needs one")
            return label, self.whole[qty], None
        if qty not in split:
            raise InputError(f"key 'body': {qty} is not split by body")
        if body not in split[qty]:
            raise InputError(f"key 'body': {body!r} is not one of {', '.join(map(str, split[qty]))}")
        if qty in ("Q_A", "M"):
            return label, self.per_body[body][qty], None
        block = self.blocks[body]
        return label, {"Phi_q": block, "Phi_r": block[:, :2], "Phi_phi": block[:, 2:]}[qty], None


# derive's hand notation as claim names; a [define] of the same name replaces it
DISPLAY_NAMES = frozenset({"dx", "dy", "dxd", "dyd"} | {f"{v}_{r}{c}" for v in "sa" for r in "ij" for c in "xy"})


def _display_names(d: DerivedConstraint) -> dict[str, sp.Expr]:
    """The hand notation `symid derive TYPE` prints, as claim names (docs/symbols.md):
    s_ix = (A_i s'_i)_x, a_ix = (A_i v'_i)_x, d = (dx, dy) = r_j + s_j - r_i - s_i, its rate (dxd, dyd)."""
    out: dict[str, sp.Expr] = {}
    for key in (k for k in d.family.keys if k.kind in ("point", "vector")):
        role, letter = key.name[1], "s" if key.kind == "point" else "a"
        gx, gy = s.A(role) * s.point(key.name)
        out[f"{letter}_{role}x"], out[f"{letter}_{role}y"] = gx, gy
    if "s_ix" in out and "s_jx" in out and "j" in d.roles:
        (xi, yi, _), (xj, yj, _) = s.q("i"), s.q("j")
        (xdi, ydi, pdi), (xdj, ydj, pdj) = s.qd("i"), s.qd("j")
        out["dx"] = xj + out["s_jx"] - xi - out["s_ix"]
        out["dy"] = yj + out["s_jy"] - yi - out["s_iy"]
        out["dxd"] = xdj - out["s_jy"] * pdj - xdi + out["s_iy"] * pdi
        out["dyd"] = ydj + out["s_jx"] * pdj - ydi - out["s_ix"] * pdi
    return out


class TypeSubject:
    """One constraint type on the generic symbols of docs/symbols.md."""

    def __init__(self, name: str, options: Mapping[str, str]) -> None:
        try:
            family = registry_lookup(CONSTRAINTS, name, "constraint type")
        except LookupError as exc:
            raise InputError(str(exc)) from None
        for key in family.keys:
            if key.kind == "choice" and options.get(key.name) not in key.choices:
                raise InputError(f"needs options.{key.name} = one of {', '.join(key.choices)} "
                                 f"(in [claim]: options = {{ {key.name} = \"{key.choices[-1]}\" }})")
        self.der = derive_constraint(name, family.variant(dict(options)))
        self.label = name + "".join(f" ({k} = {v})" for k, v in options.items())

    def names(self) -> dict[str, sp.Expr]:
        d = self.der
        roles = [x for r in d.roles for x in (*s.q(r), *s.qd(r))]
        own = {x.name: x for x in (*roles, *d.constants, *d.functions, *d.lam)}
        return {"t": s.T, **_display_names(d), **own}

    def quantity(self, qty: Any, body: Any, constraint: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]:
        if constraint is not None:
            raise InputError("key 'constraint': only a mechanism claim names constraints")
        d = self.der
        return View({"Phi": d.phi, "nu": d.nu, "gamma": d.gamma}, d.jac, d.reactions).pick(qty, body)

    def consistent(self) -> tuple[dict[sp.Symbol, sp.Expr], str, Points]:
        subs, text = consistent_configuration(self.der)
        return subs, "consistent: " + text, random_points()


def consistent_configuration(der: DerivedConstraint) -> tuple[dict[sp.Symbol, sp.Expr], str]:
    """A parametrisation of the configurations where Phi = 0 (alpha > 0 is new)."""
    name, alpha = der.family.name, sp.Symbol("alpha", positive=True)
    (xj, yj, phij), phii = s.q("j"), s.q("i")[2]
    f, c = s.F_SERIES[0], s.scalar("C")
    a = s.A("i") * s.vector("vi")

    def pin(target: sp.Matrix) -> dict[sp.Symbol, sp.Expr]:  # move body j until d_ij = target
        d = s.global_point("j", "sj") - s.global_point("i", "si")
        return {xj: xj - d[0] + target[0], yj: yj - d[1] + target[1]}

    d = s.global_point("j", "sj") - s.global_point("i", "si")
    table: dict[str, tuple[dict[sp.Symbol, sp.Expr], str]] = {
        "revolute": (pin(sp.zeros(2, 1)), "P_j = P_i (x_j, y_j eliminated)"),
        "revolute_revolute": ({s.scalar("L"): sp.sqrt(d.dot(d))}, "L = |d_ij|"),
        "distance_driver": ({f: sp.sqrt(d.dot(d))}, "f = |d_ij|"),
        "parallel": (dict(zip(s.vector("vj"), alpha * s.rot(phii - phij) * s.vector("vi"))),
                     "a_j = alpha a_i, alpha > 0 (v'_j eliminated)"),
        "pin_in_slot": (pin(alpha * a), "d_ij = alpha a_i, alpha > 0 (x_j, y_j eliminated)"),
        "translational": ({**pin(alpha * a), s.scalar("theta0"): phij - phii},
                          "d_ij = alpha a_i, alpha > 0, theta0 = phi_j - phi_i"),
    }
    if name in table:
        return table[name]
    unknown = f if f in der.phi.free_symbols else c
    return {unknown: sp.solve(der.phi[0], unknown)[0]}, f"{unknown} solved from Phi = 0"


class MechanismSubject:
    """A whole mechanism: its bodies' coordinates, parameters at their values."""

    def __init__(self, path: Path) -> None:
        from symid.io.reader import load

        self.mech = load(path)
        self.sys = mechanism_system(self.mech)
        self.values: dict[sp.Symbol, sp.Expr] = {}
        for name, expr in self.mech.parameters.items():  # dependency order: exact values
            self.values[parameter_symbol(name)] = expr.xreplace(self.values)
        self.label = f"mechanism {self.mech.name} ({path.name})"

    def names(self) -> dict[str, sp.Expr]:
        out: dict[str, sp.Expr] = {"t": s.T, **{str(k): v for k, v in self.values.items()}}
        for b in self.mech.bodies:
            out.update({n: sp.Symbol(n, real=True) for c in s.COORDS for n in (f"{c}_{b.name}", f"{c}d_{b.name}")})
        return {**out, **{x.name: x for x in (*s.lam(1), *s.lam(2))}}

    def quantity(self, qty: Any, body: Any, constraint: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]:
        sy, bodies = self.sys, [b.name for b in self.mech.bodies]
        if constraint is None:
            jac = sy.phi_q()
            whole = {k: sp.Matrix.vstack(*v.values()) for k, v in (("Phi", sy.phi), ("nu", sy.nu), ("gamma", sy.gamma))}
            whole["Q_A"] = sp.Matrix.vstack(*sy.applied.values())
            whole["M"] = sp.diag(*[x for m, j in sy.mass.values() for x in (m, m, j)])
            per_body = {b: {"Q_A": sy.applied[b], "M": sp.diag(sy.mass[b][0], *sy.mass[b])} for b in bodies}
            blocks = {b: jac[:, 3 * n:3 * n + 3] for n, b in enumerate(bodies)}
            label, m, keys = View(whole, blocks, per_body=per_body).pick(qty, body)
        else:
            if constraint not in sy.rows:
                raise InputError(f"key 'constraint': {constraint!r} is not one of {', '.join(sy.rows)}")
            n = sy.rows[constraint][1]
            blocks = {b: sy.blocks[constraint].get(b, sp.zeros(n, 3)) for b in bodies}
            whole = {"Phi": sy.phi[constraint], "nu": sy.nu[constraint], "gamma": sy.gamma[constraint]}
            label, m, keys = View(whole, blocks, sy.reactions[constraint]).pick(qty, body)
            label += f", constraint {constraint}"
        return label, m.xreplace(self.values), keys

    def consistent(self) -> tuple[dict[sp.Symbol, sp.Expr], str, Points]:
        from symid import api

        study = api.prepare(self.mech, "reference", kind="kinematics", steps=5, outputs=("q", "qdot"))
        instants = list(study.instants())
        names = self.names()
        coords = [names[f"{c}_{b.name}"] for b in self.mech.bodies for c in s.COORDS]
        rates = [names[f"{c}d_{b.name}"] for b in self.mech.bodies for c in s.COORDS]

        def points(free: list[sp.Symbol], subs: Mapping[sp.Symbol, sp.Expr]) -> Any:
            rng = random.Random(7)
            for inst in instants:
                point = {s.T: sp.Float(repr(inst.t), 30), **{x: sp.Rational(rng.randint(-16, 16), 8) for x in free}}
                point.update(zip(coords, (sp.Float(repr(float(v)), 30) for v in inst.q)))
                qd = cast(Array, inst.qd)  # set: the study's outputs include qdot
                point.update(zip(rates, (sp.Float(repr(float(v)), 30) for v in qd)))
                yield point, f"numeric, {len(instants)} solved configurations"
        return {}, "consistent: configurations solved from Phi(q, t) = 0", points
