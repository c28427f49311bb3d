"""What a constraint or force family declares: its keys, roles and equations.

Both families (constraints in `symid.symbolic.constraints`, forces in `symid.symbolic.forces`)
describe their file keys with `Key`; the reader validates instances against
them and fills defaults, so no family parses files itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping

import sympy as sp

REQUIRED: Any = object()
F_DRIVER = sp.Symbol("f", real=True)  # a driver's function of time (symid.symbolic.symbols.F_SERIES[0])

# Key kinds:
#   body     a body name or "ground"; `role` says which generic body it is
#   point    two numbers in body coordinates (generic symbols <key>x, <key>y)
#   vector   as point
#   scalar   a constant expression of the parameters (generic symbol `symbol`)
#   function an expression of t and the parameters (a driver f, a load T...)
#   function2 two such expressions (a force's global components)
#   choice   one of `choices` (selects a variant of the equations)
#   flag     true or false
#   rows     a list of expressions, one constraint row each (`type = "expression"`)
KINDS = ("body", "point", "vector", "scalar", "function", "function2", "choice", "flag", "rows")


@dataclass(frozen=True)
class Key:
    """One key of a family's table in the mechanism file."""

    name: str
    kind: str
    default: Any = REQUIRED
    role: str | None = None
    symbol: str | None = None
    choices: tuple[str, ...] = ()
    rule: str | None = None  # "positive" (a scalar), "nonzero" (a vector): checked on reading

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def broken(self, numbers: list[float]) -> str | None:
        """What is wrong with a value (its numbers) under the key's `rule`, or None."""
        if self.rule == "positive" and not numbers[0] > 0:
            return f"must be positive, not {numbers[0]:g}"
        if self.kind == "vector" and not any(numbers):  # [0, 0] has no direction: its rows would read 0 = 0
            return f"is the zero vector {numbers}: a direction needs a nonzero length"
        return None

    def symbol_name(self) -> str:
        return self.symbol or self.name


def body(name: str, role: str | None = None, default: Any = REQUIRED) -> Key:
    return Key(name, "body", role=role or name, default=default)


def scalar(name: str, symbol: str | None = None, default: Any = REQUIRED, rule: str | None = None) -> Key:
    return Key(name, "scalar", default=default, symbol=symbol, rule=rule)


def point(name: str, default: Any = REQUIRED) -> Key:
    return Key(name, "point", default=default)


def vector(name: str, rule: str | None = None) -> Key:
    return Key(name, "vector", rule=rule)


def function(name: str, default: Any = REQUIRED, symbol: str | None = None) -> Key:
    return Key(name, "function", default=default, symbol=symbol)


@dataclass(frozen=True)
class Family:
    """Common part of a constraint or force type.

    Attributes:
        name: the `type` string of the file.
        keys: the file keys, bodies first.
        points: role -> key of the point where its reaction or load acts
            (None: the centre of mass), or a function giving that point's body
            coordinates as an expression of q (a point that moves on the body:
            a rack and pinion's pitch point).
        resolve: optional hook turning alternative keys into the canonical
            ones (a gear's radii into K); gets and returns key -> value and
            raises `ValueError(key, message)` style errors via `InputError`.
    """

    name: str
    keys: tuple[Key, ...]
    points: Mapping[str, str | None | Callable[[], sp.Matrix]]
    resolve: Callable[[dict[str, Any], str], dict[str, Any]] | None = field(default=None, compare=False)
    # a family whose variants differ in size (the user's own expressions): options -> (a count, the
    # variant's own constant symbols, beyond its keys', whose values an element holds in
    # values["constants"]). The count: a constraint's rows, a force's bodies whose state it reads.
    shape: Callable[[Mapping[str, Any]], tuple[int, tuple[sp.Symbol, ...]]] | None = field(
        default=None, compare=False)

    def own_constants(self, options: Mapping[str, Any]) -> tuple[sp.Symbol, ...]:
        """The variant's constant symbols beyond its keys' (see `shape`)."""
        return () if self.shape is None else self.shape(options)[1]

    @property
    def roles(self) -> tuple[str, ...]:
        return tuple(k.role for k in self.keys if k.kind == "body")  # type: ignore[misc]

    def variant(self, options: Mapping[str, str]) -> tuple[tuple[str, str], ...]:
        """The hashable key of the equations' variant (a coordinate choice)."""
        return tuple(sorted(options.items()))


@dataclass(frozen=True)
class ConstraintType(Family):
    """A constraint family: `phi(options)` returns its rows on generic symbols.

    With a `shape` (the user's own rows, `type = "expression"`), `at(options)`
    is the family with that variant's rows, a driver when a row has the driver
    function f.
    """

    rows: int = 1
    phi: Callable[[Mapping[str, str]], list[sp.Expr]] = field(default=lambda o: [], compare=False)
    is_driver: bool = False

    def at(self, options: Mapping[str, Any]) -> "ConstraintType":
        """The family as the variant of `options` has it (its rows, its driver flag)."""
        if self.shape is None:
            return self
        rows, _ = self.shape(options)
        driver = any(e.has(F_DRIVER) for e in self.phi(options))
        return replace(self, rows=rows, is_driver=driver)


@dataclass(frozen=True)
class ForceType(Family):
    """An applied-force family.

    `loads(options)` returns role -> (Fx, Fy, T): the force (global components)
    the element applies to that body at its point and the torque about it.
    """

    loads: Callable[[Mapping[str, str]], Mapping[str, tuple[sp.Expr, sp.Expr, sp.Expr]]] = field(
        default=lambda o: {}, compare=False
    )

    def at(self, options: Mapping[str, Any]) -> "ForceType":
        """The family as the variant of `options` has it: with a `shape`, the bodies
        whose state its expressions read as roles b1, b2, ... after its own."""
        count = 0 if self.shape is None else self.shape(options)[0]
        if not count:
            return self
        return replace(self, keys=self.keys + tuple(body(f"b{k + 1}") for k in range(count)),
                       points={**self.points, **{f"b{k + 1}": None for k in range(count)}})


def registry_lookup(registry: Mapping[str, Any], name: str, what: str) -> Any:
    """`registry[name]`, or a KeyError-free message listing the valid names."""
    try:
        return registry[name]
    except KeyError:
        valid = ", ".join(sorted(registry))
        raise LookupError(f"unknown {what} '{name}' (valid: {valid})") from None
