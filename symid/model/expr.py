"""Expressions of a mechanism file, parsed by a small whitelist grammar.

A mechanism file is untrusted text: an expression is tokenized and parsed here
into sympy objects and never reaches eval, exec, compile, ast or sympify. The
limits below make hostile or mistaken input fail promptly with an InputError
instead of hanging or crashing (deep nesting, powers with millions of digits).

Grammar, loosest first (`^` and `**` are the same operator):

    expr    := term (('+' | '-') term)*               # both in one loop, see expr()
    term    := unary (('*' | '/') unary)*
    unary   := ('+' | '-') unary | power
    power   := primary (('^' | '**') unary)?      # right-assoc., above unary minus
    primary := NUMBER | NAME | NAME '(' [expr (',' expr)*] ')' | '(' expr ')'
"""

from __future__ import annotations

import math
import numbers
import re
from fractions import Fraction
from types import MappingProxyType
from typing import Callable, Mapping, NamedTuple, cast

import sympy as sp

from symid.errors import InputError

Functions = Mapping[str, tuple[int, Callable[..., sp.Expr]]]

MAX_LENGTH = 10_000  # characters of one expression
MAX_DEPTH = 100  # nesting of parentheses, calls, unary signs and powers
MAX_LITERAL = 400  # characters of one number literal
MAX_EXPONENT_DIGITS = 4  # digits after the 'e' of a literal
MAX_LOG10 = 308  # |exponent| * log10|base| of a numeric power (a double's range)
MAX_DIGITS = 5_000  # digits of the exact integers a power may make sympy build
# Smallest magnitude that rounds to inf as a double (max + half an ulp).
_OVERFLOW = 2**1024 - 2**970
_NONFINITE = (sp.zoo, sp.nan, sp.oo, sp.S.NegativeInfinity)

MAX_LISTED = 60  # an error lists every allowed name up to this many (a message stays one readable line)

FUNCTIONS: Functions = MappingProxyType({
    "sin": (1, sp.sin), "cos": (1, sp.cos), "tan": (1, sp.tan),
    "asin": (1, sp.asin), "acos": (1, sp.acos), "atan": (1, sp.atan),
    "atan2": (2, sp.atan2),  # atan2(y, x)
    "sinh": (1, sp.sinh), "cosh": (1, sp.cosh), "tanh": (1, sp.tanh),
    "exp": (1, sp.exp), "log": (1, sp.log), "sqrt": (1, sp.sqrt),
})

_TOKEN = re.compile(r"""
    (?P<space>[ \t\r\n]+)
  | (?P<num>(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<op>\*\*|[-+*/^(),])
""", re.VERBOSE)
_AFTER_NUMBER = re.compile(r"[A-Za-z0-9_.]+")  # `1e`, `2x`, `1.5.3`, `0x1f`


class _Token(NamedTuple):
    kind: str  # "num", "name", "op" or "end"
    text: str
    col: int  # 1-based column, for messages


def _show(text: str) -> str:
    """Quote a piece of the input for a message, shortened to stay one short line."""
    return repr(text if len(text) <= 40 else text[:37] + "...")


def _log10(r: sp.Rational) -> float:
    """log10|r| of a nonzero rational, without converting huge integers to float."""
    return math.log10(abs(r.p)) - math.log10(r.q)


class _Parser:
    """Recursive descent over a token list, one method per grammar rule."""

    def __init__(self, text: str, symbols: Mapping[str, sp.Expr], where: str,
                 functions: Functions) -> None:
        self.symbols, self.where, self.functions = symbols, where, functions
        self.depth = self.pos = 0
        self.tokens = self._tokenize(text)

    def fail(self, what: str) -> InputError:
        return InputError(f"{self.where}: {what}")

    def _tokenize(self, text: str) -> list[_Token]:
        tokens, pos = [], 0
        while pos < len(text):
            m = _TOKEN.match(text, pos)
            if m is None:
                raise self.fail(f"unexpected character {text[pos]!r} at column {pos + 1}")
            if m.lastgroup == "num" and (tail := _AFTER_NUMBER.match(text, m.end())):
                bad = _show(text[pos:tail.end()])
                raise self.fail(f"malformed number {bad} at column {pos + 1}")
            # Every alternative of _TOKEN is a named group, so a match names one.
            kind = cast(str, m.lastgroup)
            if kind != "space":
                op = "^" if m.group() == "**" else m.group()  # one power operator
                tokens.append(_Token(kind, op, pos + 1))
            pos = m.end()
        if not tokens:
            raise self.fail("empty expression")
        tokens.append(_Token("end", "", len(text) + 1))
        return tokens

    def accept(self, *ops: str) -> _Token | None:
        """Consume the next token if it is one of the operators `ops`."""
        tok = self.tokens[self.pos]
        if tok.kind != "op" or tok.text not in ops:
            return None
        return self.advance()

    def advance(self) -> _Token:
        """Consume the next token, whatever it is."""
        tok = self.tokens[self.pos]
        self.pos += 1
        return tok

    def enter(self, col: int) -> None:
        # Checked by hand so that the limit never depends on Python's recursion limit.
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.fail(f"expression nested deeper than {MAX_DEPTH} levels at column {col}")

    def unexpected(self, tok: _Token) -> InputError:
        if tok.kind == "end":
            return self.fail(f"expression ends too early at column {tok.col}")
        kind = {"num": "number ", "name": "name ", "op": ""}[tok.kind]
        return self.fail(f"unexpected {kind}{_show(tok.text)} at column {tok.col}")

    def parse(self) -> sp.Expr:
        result = self.expr()
        if self.tokens[self.pos].kind != "end":
            raise self.unexpected(self.tokens[self.pos])
        # Products of legal numbers may still leave a double's range (1e300*1e300).
        if any(abs(r.p) >= _OVERFLOW * r.q for r in result.atoms(sp.Rational)):
            raise self.fail("expression contains a number too large for a double")
        if result.has(*_NONFINITE):
            raise self.fail("expression is not finite")
        return result

    def expr(self) -> sp.Expr:
        """Sums of products in one loop (not one method per level): fewer stack
        frames per nesting level leave room for sympy's own recursion."""
        terms: list[sp.Expr] = []
        factors = [self.unary()]
        while tok := self.accept("+", "-", "*", "/"):
            operand = self.unary()
            if tok.text == "/":
                if operand == 0:
                    raise self.fail(f"division by zero at column {tok.col}")
                factors.append(self.finite(sp.Pow(operand, -1), "quotient", tok.col))
            elif tok.text == "*":
                factors.append(operand)
            else:
                terms.append(sp.Mul(*factors))
                factors = [-operand if tok.text == "-" else operand]
        terms.append(sp.Mul(*factors))
        return sp.Add(*terms)  # one Add, not a chain: a long sum stays linear

    def unary(self) -> sp.Expr:
        signs = []
        while tok := self.accept("-", "+"):
            signs.append(tok.text)
            self.enter(tok.col)  # a chain of signs counts as nesting
        operand = self.power()
        self.depth -= len(signs)
        return -operand if signs.count("-") % 2 else operand

    def power(self) -> sp.Expr:
        base = self.primary()
        tok = self.accept("^")
        if tok is None:
            return base
        self.enter(tok.col)
        exponent = self.unary()  # unary, not primary: `2^-1` is allowed
        self.depth -= 1
        self.check_power(base, exponent, tok.col)
        return self.finite(sp.Pow(base, exponent), "power", tok.col)

    def check_power(self, base: sp.Expr, exponent: sp.Expr, col: int) -> None:
        """Refuse a power before sympy spends forever computing its exact value."""
        if not isinstance(exponent, sp.Rational) or exponent == 0:
            return  # sympy leaves a symbolic exponent unevaluated
        log_e = _log10(exponent)
        if isinstance(base, sp.Rational) and base != 0 and _log10(base) != 0:
            if log_e + math.log10(abs(_log10(base))) > math.log10(MAX_LOG10):
                raise self.fail(f"power at column {col} is out of range: "
                                f"|exponent| * log10|base| exceeds {MAX_LOG10}")
        # sympy distributes numeric exponents into products ((2*a)^n = 2^n*a^n),
        # so every rational inside the base may be raised to it exactly.
        size = max((math.log10(max(abs(r.p), r.q)) for r in base.atoms(sp.Rational)), default=0)
        if size > 0 and log_e + math.log10(size) > math.log10(MAX_DIGITS):
            raise self.fail(f"power at column {col} is too large to compute")

    def finite(self, value: sp.Expr, what: str, col: int) -> sp.Expr:
        if value.has(*_NONFINITE):
            raise self.fail(f"{what} at column {col} is not finite")
        return value

    def primary(self) -> sp.Expr:
        tok = self.advance()
        if tok.kind == "num":
            return self.number(tok)
        if tok.kind == "op" and tok.text == "(":
            self.enter(tok.col)
            inner = self.expr()
            if not self.accept(")"):
                raise self.fail(f"expected ')' at column {self.tokens[self.pos].col} "
                                f"to close '(' at column {tok.col}")
            self.depth -= 1
            return inner
        if tok.kind != "name":
            raise self.unexpected(tok)
        if tok.text.startswith("_"):
            raise self.fail(f"names beginning with '_' are not allowed: "
                            f"{_show(tok.text)} at column {tok.col}")
        if self.accept("("):
            return self.call(tok)
        if tok.text in self.symbols:
            return self.symbols[tok.text]
        if tok.text == "pi":
            return sp.pi
        if tok.text in self.functions:
            raise self.fail(f"function {tok.text!r} at column {tok.col} "
                            f"must be called: {tok.text}(...)")
        allowed = sorted({n for n in self.symbols if not n.startswith("_")} | {"pi"})
        listed = ", ".join(allowed) if len(allowed) <= MAX_LISTED else (
            f"{len(allowed)} names: the parameters defined, t where time is allowed, pi")
        raise self.fail(f"unknown name {_show(tok.text)} at column {tok.col} (allowed: {listed})")

    def call(self, tok: _Token) -> sp.Expr:
        if tok.text not in self.functions:
            raise self.fail(f"unknown function {_show(tok.text)} at column {tok.col} "
                            f"(allowed: {', '.join(sorted(self.functions))})")
        arity, build = self.functions[tok.text]
        self.enter(tok.col)
        args = [] if self.accept(")") else [self.expr()]
        while args and not self.accept(")"):
            if not self.accept(","):
                raise self.fail(f"expected ',' or ')' at column {self.tokens[self.pos].col} "
                                f"in the call of {tok.text}() at column {tok.col}")
            args.append(self.expr())
        self.depth -= 1
        if len(args) != arity:
            raise self.fail(f"{tok.text}() at column {tok.col} takes {arity} "
                            f"argument{'s' if arity != 1 else ''}, got {len(args)}")
        if build is sp.exp:
            # exp(c*log(x)) evaluates to x**c: guard it like the power it becomes.
            for term in sp.Add.make_args(args[0]):
                coeff, rest = term.as_coeff_Mul()
                if rest.has(sp.log):
                    self.check_power(rest, coeff, tok.col)
        try:
            value = build(*args)
        except ValueError as exc:  # a builder refusing its arguments (a motion law's duration)
            raise self.fail(f"{tok.text}() at column {tok.col}: {exc}") from None
        return self.finite(value, f"{tok.text}()", tok.col)

    def number(self, tok: _Token) -> sp.Expr:
        """The exact rational a decimal literal denotes, refusing what no double can hold."""
        if len(tok.text) > MAX_LITERAL:
            raise self.fail(f"number at column {tok.col} is longer than {MAX_LITERAL} characters")
        if len(tok.text.lower().partition("e")[2].lstrip("+-")) > MAX_EXPONENT_DIGITS:
            raise self.fail(f"exponent of number {_show(tok.text)} at column {tok.col} "
                            f"has more than {MAX_EXPONENT_DIGITS} digits")
        value = Fraction(tok.text)  # exact: 0.1 is 1/10, not the double nearest it
        if abs(value) >= _OVERFLOW:
            raise self.fail(f"number {_show(tok.text)} at column {tok.col} "
                            "is too large for a double")
        return sp.Rational(value.numerator, value.denominator)


def parse_expression(source: str | int | float, symbols: Mapping[str, sp.Expr], where: str,
                     functions: Functions | None = None) -> sp.Expr:
    """Turn a TOML value (int, float or expression text) into an exact sympy expression.

    `symbols` maps every name the text may use to its sympy object (`pi` is
    always allowed unless shadowed); `functions` adds to / overrides FUNCTIONS;
    `where` (file and key) starts every message of the InputError raised.
    """
    if isinstance(source, bool):  # bool is an int subclass; TOML true is no number
        raise InputError(f"{where}: expected a number or an expression, got a boolean")
    if isinstance(source, numbers.Integral):
        if abs(int(source)) >= _OVERFLOW:
            raise InputError(f"{where}: integer is too large for a double")
        return sp.Integer(int(source))
    if isinstance(source, float):
        if not math.isfinite(source):
            raise InputError(f"{where}: number {source} is not finite")
        # The shortest decimal that round-trips: evaluating gives back the same double.
        return sp.Rational(repr(float(source)))
    if not isinstance(source, str):
        kind = type(source).__name__
        raise InputError(f"{where}: expected a number or an expression, got {kind}")
    if len(source) > MAX_LENGTH:
        raise InputError(f"{where}: expression is longer than {MAX_LENGTH} characters")
    try:
        return _Parser(source, symbols, where, {**FUNCTIONS, **(functions or {})}).parse()
    except RecursionError:  # a safety net only: MAX_DEPTH keeps well inside the default stack
        raise InputError(f"{where}: expression is nested too deeply") from None
