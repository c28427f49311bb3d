"""Read and validate a mechanism file (contract v1) into a `Mechanism`.

Every problem becomes one `InputError` line naming the file and the key.
Expressions go through the whitelist parser of `symid.model.expr`, never eval.
"""

from __future__ import annotations

import re
import tomllib
from collections import ChainMap
from pathlib import Path
from typing import Any, Mapping

import sympy as sp

from symid.symbolic.constraints import TYPES as CONSTRAINTS, family_of
from symid.model.elements import Family, Key
from symid.errors import InputError
from symid.model.expr import FUNCTIONS
from symid.symbolic.forces import TYPES as FORCES
from symid.io.files import read_text
from symid.io.analysis_table import ANALYSIS_KEYS  # noqa: F401 (the file's keys, read by tests and docs)
from symid.io import analysis_table, expressions, friction as friction_table, signals, sizing, state
from symid.io.limits import MAX_NAME_LENGTH, MAX_BODIES, MAX_CONSTRAINTS, MAX_FORCES, MAX_PARAMETERS
from symid.io.table import read as read_table
from symid.model.mechanism import GROUND, INERTIALS, T, Analysis, Body, Element, Mechanism, parameter_symbol
from symid.model.motion import LAWS, check_spans
from symid.model.sizing import Sizing
from symid.model.params import is_derived, order_parameters, parameter_values, to_float
from symid.text import plural

IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
TOP_KEYS = ("mechanism", "parameters", "signals", "analysis", "body", "constraint", "force", "drive")
MECHANISM_KEYS = ("name", "gravity")
BODY_KEYS = ("name", "mass", "inertia", "q0")
RESERVED = {"t", "pi", GROUND} | set(FUNCTIONS)


def load(path: str | Path, set_values: Mapping[str, str] | None = None,
         analysis: Mapping[str, Any] | None = None) -> Mechanism:
    """Read a mechanism file.

    Args:
        path: the TOML file.
        set_values: parameter name -> expression text replacing its value.
        analysis: `[analysis]` keys overriding the file's (from the command line).
    """
    path = Path(path)
    return loads(read_text(path), str(path), set_values, analysis)


def loads(text: str, source: str = "<string>", set_values: Mapping[str, str] | None = None,
          analysis: Mapping[str, Any] | None = None) -> Mechanism:
    """Parse mechanism-file text; `source` names it in messages."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: TOML syntax error: {exc}") from None
    except RecursionError:
        raise InputError(f"{source}: TOML nested too deeply") from None
    return _Reader(source).mechanism(data, dict(set_values or {}), dict(analysis or {}))


class _Reader:
    def __init__(self, source: str) -> None:
        self.source = source
        self.params: dict[str, sp.Symbol] = {}
        self.values: dict[sp.Symbol, float] = {}
        self.bearings: list[Any] = []  # the revolutes' `bearing` tables, in file order
        self.signals: dict[str, sp.Expr] = {}
        # expressions parsed (and evaluated), for the names (values) they were parsed with: `expr`, `number`
        self._parsed: tuple[Any, Any, dict[tuple[bool, type, Any], sp.Expr]] = (None, None, {})
        self._numbers: tuple[Any, dict[sp.Expr, float]] = (None, {})

    def fail(self, where: str, message: str) -> InputError:
        return InputError(f"{self.source}: {where}: {message}")

    # -- generic checks -------------------------------------------------
    def table(self, data: Any, where: str) -> dict[str, Any]:
        if not isinstance(data, dict):
            raise self.fail(where, f"must be a table, not {_kind(data)}")
        return data

    def unknown(self, data: Mapping[str, Any], allowed: Any, where: str) -> None:
        extra = [k for k in data if k not in allowed]
        if extra:
            raise self.fail(f"{where} key '{extra[0]}'", f"unknown key (allowed: {', '.join(allowed)})")

    def require(self, data: Mapping[str, Any], key: str, where: str) -> Any:
        if key not in data:
            raise self.fail(where, f"missing key '{key}'")
        return data[key]

    def expr(self, value: Any, where: str, time: bool = False) -> sp.Expr:
        if not isinstance(value, (str, int, float)) or isinstance(value, bool):
            raise self.fail(where, f"must be a number or an expression string, not {_kind(value)}")
        bodies = getattr(self, "state_bodies", None)
        if time and bodies:  # a point force's or torque's expression: it may read the state
            got = signals.parse(value, ChainMap(self.params, state.names(bodies)), self.signals, time,  # type: ignore[arg-type]
                                f"{self.source}: {where}", lambda message: self.fail(where, message),
                                state.functions(bodies))
            state.check(got, bodies, where, self.fail)
            return got
        if time:
            expressions.refuse_state(value, where, self.fail, f"forces of type {' and '.join(state.TYPES)} only")
        # A text met again (a ladder's 1024 "-a/2", "m_r", 0.0) is the same expression while the names
        # it may read are: parsed once (an error is raised each time, naming its own key).
        if self._parsed[0] is not self.params or self._parsed[1] is not self.signals:
            self._parsed = (self.params, self.signals, {})
        key = (time, type(value), value)
        got = self._parsed[2].get(key)
        if got is None:
            got = self._parsed[2][key] = signals.parse(value, self.params, self.signals, time,
                                                       f"{self.source}: {where}",
                                                       lambda message: self.fail(where, message))
        return got

    def signal(self, value: Any, where: str) -> sp.Expr:
        expressions.refuse_state(value, where, self.fail, "a signal is an expression of t and the parameters "
                                 "(write the state in the force that uses it)")
        return self.expr(value, where, time=True)

    def row(self, value: Any, where: str, coordinates: Mapping[str, sp.Expr]) -> sp.Expr:
        """An expression constraint's row: of the coordinates, t, the parameters and the signals."""
        if not isinstance(value, (str, int, float)) or isinstance(value, bool):
            raise self.fail(where, f"must be an expression string, not {_kind(value)}")
        return signals.parse(value, ChainMap(coordinates, self.params), self.signals, True,  # type: ignore[arg-type]
                             f"{self.source}: {where}", lambda message: self.fail(where, message))

    def number(self, value: Any, where: str) -> tuple[sp.Expr, float]:
        expr = self.expr(value, where)
        if self._numbers[0] is not self.values:  # the values an expression evaluates with
            self._numbers = (self.values, {})
        got = self._numbers[1].get(expr)
        if got is None:
            try:
                got = self._numbers[1][expr] = to_float(expr, self.values)
            except ValueError as exc:
                raise self.fail(where, str(exc.args[1])) from None
        return expr, got

    def pair(self, value: Any, where: str, time: bool = False, n: int = 2) -> tuple[sp.Expr, ...]:
        if not isinstance(value, list):
            raise self.fail(where, f"must be a list of {n} numbers or expressions, not {_kind(value)}")
        if len(value) != n:
            raise self.fail(where, f"has {plural(len(value), 'value')}, {n} expected")
        if time:
            return tuple(self.expr(v, where, time=True) for v in value)
        return tuple(self.number(v, where)[0] for v in value)

    def name(self, data: Mapping[str, Any], where: str) -> str:
        name = self.require(data, "name", where)
        if not isinstance(name, str) or not IDENTIFIER.match(name):
            shown = name[:MAX_NAME_LENGTH] if isinstance(name, str) else name
            raise self.fail(f"{where} key 'name'", f"{shown!r} is not a name (letters, digits, _)")
        if len(name) > MAX_NAME_LENGTH:
            raise self.fail(f"{where} key 'name'", f"{name[:20]}... has {len(name)} characters, more than "
                            f"the {MAX_NAME_LENGTH} allowed (it becomes a file name and C identifiers)")
        return name

    # -- sections ---------------------------------------------------------
    def mechanism(self, data: dict[str, Any], set_values: dict[str, str],
                  overrides: dict[str, Any]) -> Mechanism:
        self.unknown(data, TOP_KEYS, "top level")
        head = self.table(self.require(data, "mechanism", "top level"), "[mechanism]")
        self.unknown(head, MECHANISM_KEYS, "[mechanism]")
        name = self.name(head, "[mechanism]")
        if name.startswith("_"):  # the prefix of every C identifier: `_` gave `__real`, a GCC keyword
            raise self.fail("[mechanism] key 'name'", f"{name!r} starts with '_': it prefixes every identifier of "
                            "the generated C, where a leading _ is reserved for the compiler (start with a letter)")
        table = self.table(data.get("signals", {}), "[signals]")
        self.signals = signals.begin(table, data, RESERVED | set(LAWS), self.fail)  # name -> placeholder
        parameters = self.parameters(self.table(data.get("parameters", {}), "[parameters]"), set_values)
        self.signals = signals.read(table, self.signal, self.fail)  # -> expr
        gravity = self.pair(head.get("gravity", [0, 0]), "[mechanism] key 'gravity'")
        analysis = self.analysis(self.table(data.get("analysis", {}), "[analysis]"), overrides)
        for key, limit in (("body", MAX_BODIES), ("constraint", MAX_CONSTRAINTS), ("force", MAX_FORCES)):
            if (count := len(self.array(data, key))) > limit:  # what the reader holds before any estimate
                raise self.fail(f"[[{key}]]", f"{count} entries, more than the {limit} allowed")
        bodies = tuple(self.body(b, n) for n, b in enumerate(self.array(data, "body")))
        names: dict[str, str] = {}
        for b in bodies:
            if b.name in names or b.name == GROUND:
                raise self.fail(f"body '{b.name}' key 'name'", "duplicate or reserved name")
            names[b.name] = "body"
        if not bodies:
            raise self.fail("top level", "no [[body]]: a mechanism needs at least one body")
        constraints = tuple(self.element(c, n, "constraint", CONSTRAINTS, names)
                            for n, c in enumerate(self.array(data, "constraint")))
        forces = tuple(self.element(f, n, "force", FORCES, names)
                       for n, f in enumerate(self.array(data, "force")))
        drives = sizing.drives(data.get("drive", []), constraints, self.number, self.fail)
        mech = Mechanism(name=name, bodies=bodies, constraints=constraints, forces=forces,
                         parameters=parameters, gravity=gravity, analysis=analysis,  # type: ignore[arg-type]
                         source=self.source, sizing=Sizing(drives, tuple(self.bearings)))
        self.check_reactions(mech)
        self.check_counts(mech)
        q0 = {b.name: b.q0 for b in bodies}
        for c in constraints:
            if c.type == "expression":  # its rows dependent at q0 are named, before any solve
                expressions.check_rank(c, q0, analysis.t0, self.values, self.source)
        check_spans(mech)  # a tabled function is never extrapolated
        return mech

    def array(self, data: Mapping[str, Any], key: str) -> list[Any]:
        items = data.get(key, [])
        if not isinstance(items, list):
            raise self.fail(f"[[{key}]]", f"must be an array of tables ([[{key}]]), not {_kind(items)}")
        return items

    def parameters(self, table: dict[str, Any], set_values: dict[str, str]) -> dict[str, sp.Expr]:
        for name in set_values:
            if name not in table:
                raise self.fail(f"--set {name}", f"no such parameter (parameters: {', '.join(table) or 'none'})")
        raw = {**table, **set_values}
        if len(raw) > MAX_PARAMETERS:
            raise self.fail("[parameters]", f"{len(raw)} parameters, more than the {MAX_PARAMETERS} allowed")
        for name in raw:
            if len(name) > MAX_NAME_LENGTH:
                raise self.fail(f"[parameters] key '{name[:20]}...'", f"has {len(name)} characters, more than "
                                f"the {MAX_NAME_LENGTH} allowed (it becomes a C identifier)")
            if not IDENTIFIER.match(name) or name in RESERVED or name.startswith("_"):
                raise self.fail(f"[parameters] key '{name}'", "is reserved or not a valid name")
        self.params = {n: parameter_symbol(n) for n in raw}
        exprs = {n: self.expr(v, f"[parameters] key '{n}'" if n not in set_values else f"--set {n}")
                 for n, v in raw.items()}
        for name in set_values:  # after the values parse: their own errors come first
            self.base_only(name, table[name])
        try:
            order = order_parameters(exprs)
        except ValueError as exc:
            raise self.fail("[parameters]", f"parameters defined in a cycle: {exc}") from None
        ordered = {n: exprs[n] for n in order}
        try:
            self.values = parameter_values(ordered)
        except ValueError as exc:
            raise self.fail(f"[parameters] key '{exc.args[0]}'", str(exc.args[1])) from None
        return {n: exprs[n] for n in order}

    def base_only(self, name: str, value: Any) -> None:
        """Refuse `--set` of a derived parameter: it is recomputed from its definition."""
        defined = self.expr(value, f"[parameters] key '{name}'")
        if is_derived(defined):
            uses = ", ".join(sorted(str(x) for x in defined.free_symbols))
            raise self.fail(f"--set {name}", f"'{name}' is a derived parameter ({name} = \"{value}\" in "
                            f"[parameters]); set the base parameters it is computed from ({uses})")

    def analysis(self, table: dict[str, Any], overrides: dict[str, Any]) -> Analysis:
        return analysis_table.read(table, overrides, self.fail, self.unknown)

    def body(self, data: Any, n: int) -> Body:
        where = f"[[body]] #{n + 1}"
        data = self.table(data, where)
        name = self.name(data, where)
        where = f"body '{name}'"
        self.unknown(data, BODY_KEYS, where)
        mass, inertia = (self.inertial(data, key, where) for key in INERTIALS)
        q0 = self.pair(self.require(data, "q0", where), f"{where} key 'q0'", n=3)
        return Body(name=name, mass=mass, inertia=inertia, q0=q0)  # type: ignore[arg-type]

    def inertial(self, data: Mapping[str, Any], key: str, where: str) -> sp.Expr:
        expr, value = self.number(self.require(data, key, where), f"{where} key '{key}'")
        if value < 0:
            raise self.fail(f"{where} key '{key}'", f"must not be negative (it is {value:g})")
        return expr

    def element(self, data: Any, n: int, section: str, registry: Mapping[str, Family],
                names: dict[str, str]) -> Element:
        where = f"[[{section}]] #{n + 1}"
        data = self.table(data, where)
        name = self.name(data, where)
        where = f"{section} '{name}'"
        if name in names or name == GROUND:
            raise self.fail(f"{where} key 'name'", f"duplicate name (already a {names.get(name, 'reserved name')})")
        kind = self.require(data, "type", where)
        if kind not in registry:
            raise self.fail(f"{where} key 'type'",
                            f"unknown {section} type {kind!r} (valid: {', '.join(sorted(registry))})")
        family = registry[kind]
        friction = {} if "friction" not in data or section != "constraint" else friction_table.read(
            data["friction"], kind, where, self.source, self.number)
        if "bearing" in data and section == "constraint":
            self.bearings.append(sizing.bearing(data["bearing"], name, kind, where, self.number, self.fail))
        self.unknown(data, ("name", "type") + tuple(k.name for k in family.keys)
                     + (("friction", "bearing") if section == "constraint" else ()), where)
        bodies: dict[str, str] = {}
        values: dict[str, Any] = {}
        options: dict[str, str] = {}
        reads_state = section == "force" and kind in state.TYPES
        # only a force that reads a body's state lists the bodies (once per element: quadratic in the file)
        readable = [n for n, what in names.items() if what == "body"] if reads_state else []
        self.state_bodies = readable if reads_state else None
        for key in family.keys:
            kw = f"{where} key '{key.name}'"
            if key.name not in data:
                if key.required:
                    raise self.fail(where, f"missing key '{key.name}'")
                if key.kind == "body":  # an expression constraint's j: ground
                    bodies[key.role] = key.default  # type: ignore[index]
                elif key.kind == "point":
                    values[key.name] = tuple(sp.Integer(v) for v in key.default)
                elif key.kind == "flag":
                    values[key.name] = key.default
                elif key.default is not None:
                    values[key.name] = self.expr(key.default, kw)
                continue
            raw = data[key.name]
            if key.kind == "body":
                bodies[key.role] = self.body_name(raw, kw, names)  # type: ignore[index]
            elif key.kind == "rows":  # an expression constraint's own rows
                given = {r: b for r, b in bodies.items() if r != "j" or "j" in data}
                more, options = expressions.read(raw, kw, given, self.params, self.row, self.fail)
                values.update(more)
            else:
                value = self.value(key, raw, kw)
                if key.kind == "choice":
                    options[key.name] = value
                else:
                    values[key.name] = value
        self.state_bodies = None
        if reads_state:  # its terms of the state become its variant
            timed = tuple(k.name for k in family.keys if k.kind in ("function", "function2"))
            more, more_options, extra = state.generalize(values, timed, bodies["i"], readable,
                                                         set(self.params.values()), where, self.fail)
            values.update(more)
            options.update(more_options)
            bodies.update(extra)
        if family.resolve is not None:
            try:
                values = family.resolve(values, where)
            except ValueError as exc:
                raise InputError(f"{self.source}: {exc}") from None
            for k, v in values.items():
                if isinstance(v, sp.Expr) and not v.has(T):
                    self.finite(v, f"{where} key '{k}'")
        if len(set(bodies.values())) != len(bodies):
            raise self.fail(where, f"connects a body to itself ({', '.join(bodies.values())})")
        if all(b == GROUND for b in bodies.values()):
            raise self.fail(where, "acts on ground only")
        names[name] = section
        return Element(name=name, type=kind, bodies=bodies, values=values, options=options, friction=friction)

    def finite(self, expr: sp.Expr, where: str) -> None:
        try:
            to_float(expr, self.values)
        except ValueError as exc:
            raise self.fail(where, str(exc.args[1])) from None

    def body_name(self, raw: Any, where: str, names: Mapping[str, str]) -> str:
        if raw == GROUND:
            return GROUND
        if not isinstance(raw, str) or names.get(raw) != "body":
            bodies = [n for n, kind in names.items() if kind == "body"]
            raise self.fail(where, f"unknown body {raw!r} (bodies: {', '.join(bodies)}, ground)")
        return raw

    def value(self, key: Key, raw: Any, where: str) -> Any:
        if key.kind in ("point", "vector", "scalar"):
            got = self.pair(raw, where) if key.kind != "scalar" else (self.number(raw, where)[0],)
            if problem := key.broken([to_float(v, self.values) for v in got]):  # r > 0, a direction not zero
                raise self.fail(where, problem)
            return got if key.kind != "scalar" else got[0]
        if key.kind == "function" and isinstance(raw, dict):
            return read_table(raw, self.source, where)  # f = { table = "motion.csv", column = ... }
        if key.kind == "function":
            return self.expr(raw, where, time=True)
        if key.kind == "function2":
            return self.pair(raw, where, time=True)
        if key.kind == "choice":
            if raw not in key.choices:
                raise self.fail(where, f"must be one of {', '.join(map(repr, key.choices))}, not {raw!r}")
            return raw
        if not isinstance(raw, bool):
            raise self.fail(where, f"must be true or false, not {raw!r}")
        return raw

    def check_reactions(self, mech: Mechanism) -> None:
        wanted = mech.analysis.reactions
        known = [c.name for c in mech.constraints]
        for name in wanted or ():
            if name not in known:
                raise self.fail("[analysis] key 'reactions'",
                                f"unknown constraint {name!r} (constraints: {', '.join(known)})")

    def check_counts(self, mech: Mechanism) -> None:
        ng = 3 * len(mech.bodies)
        nc = sum(family_of(c).rows for c in mech.constraints)
        if nc < ng:
            raise self.fail("[[constraint]]", f"{nc} constraint rows for {ng} coordinates: "
                            f"{ng - nc} missing (inverse dynamics needs one driver per degree of freedom)")
        # nc > ng is judged numerically (which rows are redundant) when the
        # study is prepared: symid.backends.check_redundant


def _kind(value: Any) -> str:
    return {dict: "a table", list: "a list", str: "a string", bool: "a boolean"}.get(
        type(value), type(value).__name__)
