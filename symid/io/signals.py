"""The `[signals]` table: named expressions of t, written once, used by name.

A signal is an expression of `t`, the parameters, the motion laws and other
signals (no cycles). It is replaced by its expression wherever it is used, when
the file is read, so everything after the reader (derivation, every backend,
generated code) sees plain expressions of t and the parameters.
"""

from __future__ import annotations

import re
from collections import ChainMap
from typing import Any, Callable, Mapping

import sympy as sp

from symid.errors import InputError
from symid.io.limits import MAX_NAME_LENGTH
from symid.model.expr import parse_expression
from symid.model.mechanism import T
from symid.model.motion import LAWS
from symid.model.params import order_parameters

Fail = Callable[[str, str], InputError]
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")


def placeholder(name: str) -> sp.Symbol:
    """A signal's stand-in while the file is read: no file can name it (a leading _)."""
    return sp.Symbol("_signal_" + name, real=True)


def check_names(table: Mapping[str, Any], taken: Mapping[str, str], fail: Fail) -> None:
    """Refuse a signal name that is no name or shadows a name in `taken` (name -> what it is)."""
    for name in table:
        where = f"[signals] key '{name}'"
        if len(name) > MAX_NAME_LENGTH or not _NAME.match(name):
            raise fail(where, "is not a valid name (letters, digits, _; not starting with _)")
        if name in taken:
            raise fail(where, f"shadows the {taken[name]} '{name}': give the signal another name")


def begin(table: Mapping[str, Any], data: Mapping[str, Any], builtins: set[str], fail: Fail) -> dict[str, sp.Expr]:
    """Check the table's names against the file's (`data`: the whole file, read before its
    parameters and bodies are) and return their placeholders: a parameter or other constant
    that names a signal is then told why it may not."""
    parameters, bodies = data.get("parameters"), data.get("body")
    taken = {n: "built-in" for n in builtins}
    taken.update({b["name"]: "body" for b in bodies if isinstance(b, dict) and isinstance(b.get("name"), str)}
                 if isinstance(bodies, list) else {})
    taken.update({n: "parameter" for n in parameters} if isinstance(parameters, dict) else {})
    check_names(table, taken, fail)
    return {n: placeholder(n) for n in table}


def read(table: Mapping[str, Any], parse: Callable[[Any, str], sp.Expr], fail: Fail) -> dict[str, sp.Expr]:
    """name -> its expression with the signals it uses substituted. `parse(value, where)`
    parses an expression of t in which every signal name is its `placeholder`."""
    raw = {n: parse(v, f"[signals] key '{n}'") for n, v in table.items()}
    try:
        order = order_parameters(raw, placeholder)
    except ValueError as exc:
        raise fail("[signals]", f"signals defined in a cycle: {exc}") from None
    done: dict[str, sp.Expr] = {}
    for name in order:
        done[name] = raw[name].xreplace({placeholder(n): done[n] for n in done})
    return {n: done[n] for n in table}


def parse(value: Any, symbols: Mapping[str, sp.Expr], signals: Mapping[str, sp.Expr], time: bool, where: str,
          fail: Callable[[str], InputError], functions: Mapping[str, Any] | None = None) -> sp.Expr:
    """An expression of the file (`parse_expression`) of `symbols`, and of t and the signals where
    time is allowed (`time`: a signal's name stands for its expression); a constant (a parameter, a mass, a point) naming one
    is refused, with the reason."""
    # a view, not a copy: a file of 10^4 parameters parses 10^4 expressions
    names = ChainMap(signals, {"t": T}, symbols) if time else ChainMap({n: placeholder(n) for n in signals}, symbols)
    expr = parse_expression(value, names, where, functions={**LAWS, **functions} if functions else LAWS)
    used = [] if time else sorted(n for n in signals if placeholder(n) in expr.free_symbols)
    if used:
        raise fail(f"uses the signal '{used[0]}', a function of t: this value is a constant "
                   "(an expression of the parameters only)")
    return expr
