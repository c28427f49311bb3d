"""How numbers and counts read in messages (tables keep full precision)."""

from __future__ import annotations


def number(x: float) -> str:
    """A value with the digits that matter: 12 significant, so a time on the
    grid t0 + k h reads `0.05`, not its rounding `0.050000000000000003`."""
    return f"{float(x):.12g}"


def plural(n: int, word: str, many: str | None = None) -> str:
    """`1 Newton iteration`, `2 Newton iterations`."""
    return f"{n} {word if n == 1 else (many or word + 's')}"
