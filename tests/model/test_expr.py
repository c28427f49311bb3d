"""Tests of the whitelist expression parser `symid.model.expr`."""

from __future__ import annotations

import cmath
import math
import random
import re
import time
from pathlib import Path
from typing import Callable

import pytest
import sympy as sp

from symid.errors import InputError
from symid.model.expr import FUNCTIONS, MAX_DEPTH, MAX_LENGTH, parse_expression
from symid.model.mechanism import T, parameter_symbol

A, B = parameter_symbol("a"), parameter_symbol("b")
SYMBOLS = {"a": A, "b": B, "t": T}
WHERE = "slider_crank.toml: constraint 'motor' key 'f'"
NONFINITE = (sp.zoo, sp.nan, sp.oo, -sp.oo)


def parse(source: str | int | float, **kwargs) -> sp.Expr:
    return parse_expression(source, SYMBOLS, WHERE, **kwargs)


def assert_rejected(source: object, problem: str) -> str:
    """Parsing `source` raises a one-line InputError naming WHERE and matching `problem`."""
    with pytest.raises(InputError, match=problem) as info:
        parse(source)  # type: ignore[arg-type]
    message = str(info.value)
    assert message.startswith(WHERE + ": ")
    assert "\n" not in message
    return message


def elapsed(action: Callable[[], object]) -> float:
    """CPU seconds `action` takes, whether it returns or raises InputError: the
    process's own work, which a loaded machine does not stretch as it does the
    wall clock (the bounds say "no super-linear parse", not how fast)."""
    start = time.process_time()
    try:
        action()
    except InputError:
        pass
    return time.process_time() - start


# --- precedence and associativity -------------------------------------------

def test_unary_minus_binds_looser_than_power() -> None:
    assert parse("-a^2") == -(A**2)
    assert parse("-a**2") == -(A**2)
    assert parse("(-a)^2") == A**2
    assert parse("-2^2") == -4


def test_power_is_right_associative() -> None:
    assert parse("2^3^2") == 512
    assert parse("2**3**2") == 512
    assert parse("a^b^t") == A ** (B**T)
    assert parse("(2^3)^2") == 64


def test_power_accepts_a_signed_exponent() -> None:
    assert parse("2**-1") == sp.Rational(1, 2)
    assert parse("2^-1") == sp.Rational(1, 2)
    assert parse("2^+3") == 8
    assert parse("a^-b^2") == A ** (-(B**2))


def test_subtraction_and_division_are_left_associative() -> None:
    assert parse("a-b-t") == A - B - T
    assert parse("a/b/t") == A / (B * T)
    assert parse("8/4/2") == 1
    assert parse("8-4-2") == 2


def test_products_bind_tighter_than_sums() -> None:
    assert parse("a+b*t") == A + B * T
    assert parse("(a+b)*t") == (A + B) * T
    assert parse("a*-b") == -A * B
    assert parse("a - -b") == A + B


def test_repeated_signs_and_whitespace() -> None:
    assert parse("--a") == A
    assert parse("-+-a") == A
    assert parse(" \t a\n+\r\nb ") == A + B


# --- names and functions -----------------------------------------------------

@pytest.mark.parametrize("name", sorted(n for n, (arity, _) in FUNCTIONS.items() if arity == 1))
def test_every_one_argument_function(name: str) -> None:
    assert parse(f"{name}(a + 1)") == FUNCTIONS[name][1](A + 1)


def test_atan2_takes_y_then_x() -> None:
    assert parse("atan2(a, b)") == sp.atan2(A, B)
    assert parse("atan2(1, 0)") == sp.pi / 2
    assert parse("atan2(0, -1)") == sp.pi


@pytest.mark.parametrize(("text", "problem"), [
    ("sin()", r"sin\(\) at column 1 takes 1 argument, got 0"),
    ("sin(a, b)", r"sin\(\) at column 1 takes 1 argument, got 2"),
    ("atan2(a)", r"atan2\(\) at column 1 takes 2 arguments, got 1"),
    ("1 + atan2(a, b, t)", r"atan2\(\) at column 5 takes 2 arguments, got 3"),
])
def test_function_arity_is_checked(text: str, problem: str) -> None:
    assert_rejected(text, problem)


def test_pi_is_sympy_pi_unless_shadowed() -> None:
    assert parse("pi") is sp.pi
    assert parse("2*pi") == 2 * sp.pi
    shadow = parameter_symbol("pi")
    assert parse_expression("pi", {"pi": shadow}, WHERE) is shadow


def test_extra_functions_add_to_and_override_the_table() -> None:
    extra = {"ramp": (2, lambda x, y: x * y + 1), "sin": (1, sp.cos)}
    assert parse("ramp(a, t)", functions=extra) == A * T + 1
    assert parse("sin(a)", functions=extra) == sp.cos(A)
    assert parse("cos(a)", functions=extra) == sp.cos(A)
    assert "ramp" not in FUNCTIONS  # the shared table is not mutated
    assert_rejected("ramp(a, t)", "unknown function 'ramp'")


def test_results_use_exactly_the_symbols_passed_in() -> None:
    positive = sp.Symbol("a", positive=True)
    result = parse_expression("sqrt(a^2) + t", {"a": positive, "t": T}, WHERE)
    assert result == positive + T
    assert result.free_symbols == {positive, T}
    assert isinstance(parse("a"), sp.Expr)


# --- numbers -------------------------------------------------------------------

def test_integer_literals_are_exact_integers() -> None:
    assert isinstance(parse("12"), sp.Integer)
    assert parse("100000000000000000000001") == 10**23 + 1


@pytest.mark.parametrize(("text", "value"), [
    ("0.1", sp.Rational(1, 10)),
    (".5", sp.Rational(1, 2)),
    ("1.", sp.Integer(1)),
    ("2e-3", sp.Rational(1, 500)),
    ("1E+6", sp.Integer(10**6)),
    ("1.5e2", sp.Integer(150)),
    ("0.30000000000000004", sp.Rational(30000000000000004, 10**17)),
    ("1e-9999", sp.Rational(1, 10**9999)),
])
def test_decimal_literals_are_exact_rationals(text: str, value: sp.Rational) -> None:
    assert parse(text) == value


def test_python_ints_become_integers() -> None:
    assert parse(7) == 7 and isinstance(parse(7), sp.Integer)
    assert parse(-3) == -3


def test_python_floats_are_their_shortest_decimal() -> None:
    assert parse(0.1) == sp.Rational(1, 10)
    assert parse(-2.5) == sp.Rational(-5, 2)
    assert float(parse(0.1)) == 0.1


def test_floats_evaluate_back_to_the_same_double() -> None:
    rng = random.Random(0)
    values = [5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, 1 / 3, -0.0]
    values += [rng.uniform(-1, 1) * 10.0 ** rng.randint(-300, 300) for _ in range(500)]
    for value in values:
        assert float(parse(value)) == value
        assert float(parse(repr(value))) == value


@pytest.mark.parametrize(("source", "problem"), [
    (True, "got a boolean"),
    (False, "got a boolean"),
    (math.inf, "not finite"),
    (-math.inf, "not finite"),
    (math.nan, "not finite"),
    (None, "got NoneType"),
    ([1], "got list"),
    (10**400, "too large for a double"),
])
def test_non_numbers_and_non_finite_values_are_rejected(source: object, problem: str) -> None:
    assert_rejected(source, problem)


@pytest.mark.parametrize(("text", "problem"), [
    ("1.8e308", r"number '1\.8e308' at column 1 is too large for a double"),
    ("a + 2e308", r"number '2e308' at column 5 is too large"),
    ("1" + "0" * 309, "too large for a double"),
    ("1e99999", r"exponent of number '1e99999' at column 1 has more than 4 digits"),
    ("1e-00001", "has more than 4 digits"),
    ("1" * 500, "longer than 400 characters"),
    ("1e300*1e300", "too large for a double"),
    ("1e", r"malformed number '1e' at column 1"),
    ("1e+", "malformed number"),
    ("2x", r"malformed number '2x'"),
    ("1.5.3", r"malformed number '1\.5\.3'"),
    ("0x10", "malformed number"),
    ("1_000", "malformed number"),
])
def test_bad_numbers_are_rejected(text: str, problem: str) -> None:
    assert_rejected(text, problem)


def test_largest_double_literal_is_accepted() -> None:
    assert float(parse("1.7976931348623157e308")) == 1.7976931348623157e308


# --- rejections ----------------------------------------------------------------

@pytest.mark.parametrize(("text", "problem"), [
    ("a.b", r"unexpected character '\.' at column 2"),
    ("a[0]", r"unexpected character '\[' at column 2"),
    ("'a'", "unexpected character \"'\" at column 1"),
    ('"a"', "unexpected character '\"' at column 1"),
    ("lambda", r"unknown name 'lambda' at column 1"),
    ("lambda x: x", r"unexpected character ':' at column 9"),
    ("a, b", r"unexpected ',' at column 2"),
    ("a = b", r"unexpected character '=' at column 3"),
    ("a; b", r"unexpected character ';' at column 2"),
    ("a @ b", r"unexpected character '@' at column 3"),
    ("a \\ b", r"unexpected character '\\\\' at column 3"),
    ("a × b", r"unexpected character '×' at column 3"),
    ("_a", r"names beginning with '_' are not allowed: '_a' at column 1"),
    ("1 + __class__", r"names beginning with '_' are not allowed: '__class__' at column 5"),
    ("c", r"unknown name 'c' at column 1 \(allowed: a, b, pi, t\)"),
    ("foo(a)", r"unknown function 'foo' at column 1 \(allowed: acos, asin, atan, atan2, cos,"),
    ("sin", r"function 'sin' at column 1 must be called"),
    ("", "empty expression"),
    (" \t\n", "empty expression"),
    ("a +", "expression ends too early at column 4"),
    ("a^", "expression ends too early"),
    ("(a", r"expected '\)' at column 3 to close '\(' at column 1"),
    ("a)", r"unexpected '\)' at column 2"),
    ("()", r"unexpected '\)' at column 2"),
    ("a b", r"unexpected name 'b' at column 3"),
    ("2 3", r"unexpected number '3' at column 3"),
    ("a // b", r"unexpected '/' at column 4"),
    ("sin(a b)", r"expected ',' or '\)' at column 7 in the call of sin\(\)"),
    ("sin(a,)", r"unexpected '\)' at column 7"),
    ("1/0", "division by zero at column 2"),
    ("a/(b - b)", "division by zero at column 2"),
    ("log(0)", r"log\(\) at column 1 is not finite"),
    ("tan(pi/2)", r"tan\(\) at column 1 is not finite"),
    ("atan2(0, 0)", r"atan2\(\) at column 1 is not finite"),
    ("0^-1", "power at column 2 is not finite"),
    ("(0^-1)^0", "power at column 3 is not finite"),
])
def test_invalid_text_is_rejected_with_its_column(text: str, problem: str) -> None:
    assert_rejected(text, problem)


def test_unknown_name_lists_every_allowed_name() -> None:
    many = {f"p{i:02d}": parameter_symbol(f"p{i:02d}") for i in range(20)}
    with pytest.raises(InputError, match=r"\(allowed: p00, p01, .*, p19, pi\)") as info:
        parse_expression("q", many, WHERE)
    assert "..." not in str(info.value)


@pytest.mark.parametrize("text", [
    "__import__('os').system('touch X')",
    "__import__",
    "().__class__.__bases__[0].__subclasses__()",
    "eval('1')",
    "open('X', 'w')",
])
def test_code_injection_is_rejected_and_runs_nothing(
    text: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=re.escape(WHERE)):
        parse(text)
    assert list(tmp_path.iterdir()) == []


# --- robustness: nothing hangs or crashes ------------------------------------

@pytest.mark.parametrize("text", [
    "10^10^10",
    "(10^300)^(10^300)",
    "9^9^9^9",
    "2^2^2^2^2^2",
    "2^1025",
    "(1/2)^2000",
    "exp(10^300*log(2))",
    "exp(a + 10^300*(log(2) + log(3)))",
    "(2*a)^(10^30)",
    "sqrt(2)^(10^30)",
])
def test_huge_powers_are_refused_promptly(text: str) -> None:
    assert elapsed(lambda: assert_rejected(text, "power at column")) < 1.0


@pytest.mark.parametrize(("text", "value"), [
    ("2^1000", sp.Integer(2) ** 1000),
    ("(1/2)^1000", sp.Rational(1, 2**1000)),
    ("10^-300", sp.Rational(1, 10**300)),
    ("1^(10^300)", sp.Integer(1)),
    ("0^(10^300)", sp.Integer(0)),
    ("(-1)^(10^300)", sp.Integer(1)),
    ("a^(10^300)", A ** (10**300)),
    ("exp(3*log(2))", sp.Integer(8)),
])
def test_powers_in_range_are_exact(text: str, value: sp.Expr) -> None:
    assert parse(text) == value


@pytest.mark.parametrize("text", [
    "(" * 5000 + "a" + ")" * 5000,
    "(" * 4000 + "a" + ")" * 4000,
    "-" * 5000 + "a",
    "2^" * 3000 + "2",
    "sin(" * 2000 + "a" + ")" * 2000,
])
def test_deep_nesting_is_refused_promptly(text: str) -> None:
    problem = f"nested deeper than {MAX_DEPTH} levels|longer than {MAX_LENGTH} characters"
    assert elapsed(lambda: assert_rejected(text, problem)) < 1.0


def test_nesting_up_to_the_limit_is_accepted() -> None:
    assert parse("(" * MAX_DEPTH + "a" + ")" * MAX_DEPTH) == A
    assert parse("-" * MAX_DEPTH + "a") == A
    assert_rejected("(" * (MAX_DEPTH + 1) + "a" + ")" * (MAX_DEPTH + 1), "nested deeper")


def test_nesting_at_the_limit_leaves_stack_for_the_caller() -> None:
    def deeper(frames: int) -> sp.Expr:
        return deeper(frames - 1) if frames else parse(text)

    text = "cosh(" * MAX_DEPTH + "a + 7" + ")" * MAX_DEPTH  # not in sympy's cache yet
    expected = A + 7
    for _ in range(MAX_DEPTH):
        expected = sp.cosh(expected)
    assert deeper(300) == expected


def test_one_megabyte_string_is_refused_promptly() -> None:
    text = "a+" * 500_000 + "a"
    assert elapsed(lambda: assert_rejected(text, f"longer than {MAX_LENGTH} characters")) < 1.0


def test_long_flat_expressions_parse_promptly() -> None:
    assert elapsed(lambda: parse("+".join(["a"] * 4000))) < 1.0
    assert parse("+".join(["a"] * 4000)) == 4000 * A
    assert elapsed(lambda: parse("*".join(["a", "b", "t", "2"] * 1000))) < 1.0
    sines = "+".join(f"sin({i})" for i in range(1, 200))  # sympy's own cost dominates here
    assert elapsed(lambda: parse(sines)) < 1.0


# --- randomized round trip -------------------------------------------------------

ADD, MUL, UNARY, POWER, ATOM = 1, 2, 3, 4, 5  # precedence, loosest first


class Tree:
    """A random expression: its text, its precedence and the sympy value built directly."""

    def __init__(self, text: str, prec: int, expr: sp.Expr, bad: bool = False) -> None:
        self.text, self.prec, self.expr = text, prec, expr
        # bad: some step is singular (x/0, log(0)...), so the parser must refuse it.
        self.bad = bad or expr.has(*NONFINITE)

    def at(self, prec: int) -> str:
        """Text usable as an operand that needs at least `prec`, parenthesized if looser."""
        return self.text if self.prec >= prec else f"({self.text})"


def random_leaf(rng: random.Random) -> Tree:
    kind = rng.randrange(4)
    if kind == 0:
        name = rng.choice("abt")
        return Tree(name, ATOM, SYMBOLS[name])
    if kind == 1:
        value = rng.randint(0, 20)
        return Tree(str(value), ATOM, sp.Integer(value))
    if kind == 2:
        digits, scale = rng.randint(1, 99999), rng.randint(1, 4)
        text = rng.choice([f"{digits}e-{scale}", f"{digits / 10**scale!r}"])
        return Tree(text, ATOM, sp.Rational(digits, 10**scale))
    return Tree("pi", ATOM, sp.pi)


def random_tree(rng: random.Random, depth: int) -> Tree:
    if depth == 0 or rng.random() < 0.2:
        return random_leaf(rng)
    kind = rng.choice(["+", "-", "*", "/", "^", "neg", "call", "atan2"])
    x = random_tree(rng, depth - 1)
    if kind == "neg":
        return Tree(f"-{x.at(UNARY)}", UNARY, -x.expr, x.bad)
    if kind == "call":
        name = rng.choice([n for n, (arity, _) in FUNCTIONS.items() if arity == 1])
        return Tree(f"{name}({x.text})", ATOM, FUNCTIONS[name][1](x.expr), x.bad)
    if kind == "^":
        y = random_tree(rng, depth - 1)
        if not y.expr.free_symbols:  # small numeric exponents keep the values tame
            n = rng.randint(-3, 3)  # a signed one checks `2^-1`
            y = Tree(str(n), ATOM if n >= 0 else UNARY, sp.Integer(n))
        op = rng.choice(["^", "**"])
        return Tree(f"{x.at(ATOM)}{op}{y.at(UNARY)}", POWER, x.expr**y.expr, x.bad or y.bad)
    y = random_tree(rng, depth - 1)
    bad = x.bad or y.bad
    if kind == "atan2":
        return Tree(f"atan2({x.text}, {y.text})", ATOM, sp.atan2(x.expr, y.expr), bad)
    if kind in "+-":
        value = x.expr + y.expr if kind == "+" else x.expr - y.expr
        return Tree(f"{x.at(ADD)} {kind} {y.at(MUL)}", ADD, value, bad)
    if kind == "/" and y.expr == 0:
        return Tree(f"{x.at(MUL)}/{y.at(UNARY)}", MUL, sp.nan, True)
    value = x.expr * y.expr if kind == "*" else x.expr / y.expr
    return Tree(f"{x.at(MUL)}{kind}{y.at(UNARY)}", MUL, value, bad)


def numerically_equal(x: sp.Expr, y: sp.Expr, rng: random.Random) -> bool:
    for _ in range(3):
        point = {s: sp.Rational(rng.randint(5, 20), 10) for s in (A, B, T)}
        want = complex(sp.N(y.subs(point), 30))
        if not cmath.isfinite(want):
            continue  # singular at this point: no information
        if abs(complex(sp.N(x.subs(point), 30)) - want) > 1e-9 * (1 + abs(want)):
            return False
    return True


def test_random_expressions_round_trip() -> None:
    rng = random.Random(0)
    checked = 0
    for _ in range(300):
        tree = random_tree(rng, 4)
        if tree.bad:
            with pytest.raises(InputError):
                parse(tree.text)
            continue
        parsed = parse(tree.text)
        assert parsed == tree.expr or numerically_equal(parsed, tree.expr, rng), tree.text
        checked += 1
    assert checked > 200
