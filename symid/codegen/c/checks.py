"""What templates/c/checks.j2 needs: the trajectory's checks at sizes fixed
when the code is generated.

The finite check of an instant reads q, qd, qdd, lambda and the reactions;
where the row holds several of them side by side (the contract's order puts
them so when all are asked for) they are one block, checked in one pass.
"""

from __future__ import annotations

from dataclasses import dataclass

# values written out one statement each up to this many; loops of constant
# trip count (four lanes per pass) past it, so that a ladder's code stays small.
# 128 (the slider-crank's 66-value row block written out too) measured worse:
# 1964 instructions per sweep instant against 1889, gcc 12 -O2
STRAIGHT = 64


def blocks(checked: list[tuple[str, int | None, int]]) -> list[tuple[str, int, int]]:
    """(base, offset, count) blocks covering the checked vectors.

    Args:
        checked: per vector (its variable, its offset in the row or None, its
            size), in the row's order.
    """
    out: list[tuple[str, int, int]] = []
    for var, offset, size in checked:
        if size == 0:
            continue
        if offset is None:
            out.append((var, 0, size))
        elif out and out[-1][0] == "row" and out[-1][1] + out[-1][2] == offset:
            out[-1] = ("row", out[-1][1], out[-1][2] + size)
        else:
            out.append(("row", offset, size))
    return out


@dataclass(frozen=True)
class Checks:
    """What templates/c/checks.j2 (and simd.j2, unroll.j2) need.

    Attributes:
        blocks: (base, offset, count) of the checked values (`blocks`).
        straight: values written out one statement each up to this many.
        maxabs: the vector sizes whose largest |value| the code takes.
        looped: whether a block is past `straight`.
        rolling: whether the predictor's history stays in the rows.
    """

    blocks: list[tuple[str, int, int]]
    straight: int
    maxabs: list[int]
    looped: bool
    rolling: bool


def context(outputs: list[tuple[str, int | None, int]], ng: int, nc: int, velocity: bool, multipliers: bool,
            nr: int) -> Checks:
    """The trajectory's checks.

    Args:
        outputs: the trajectory's output vectors (variable, row offset or
            None, work vector), as compose.context builds them: qn, qdn, qddn, lam, reac.
    """
    sizes = {"qn": ng, "qdn": ng if velocity else 0, "qddn": ng if velocity else 0,
             "lam": nc if multipliers else 0, "reac": nr}
    checked = sorted(((var, offset, sizes[var]) for var, offset, _ in outputs),
                     key=lambda v: (v[1] is None, v[1] or 0))
    found = blocks(checked)
    placed = {var for var, offset, _ in outputs if offset is not None}
    # the predictor's history can stay in the rows when they hold all of it
    rolling = {"qn", "qdn", "qddn"} <= placed if velocity else "qn" in placed
    return Checks(blocks=found, straight=STRAIGHT, maxabs=sorted({ng, nc} - {0}),
                  looped=any(n > STRAIGHT for _, _, n in found), rolling=rolling)
