"""Target-independent preparation of the generated code: CSE'd blocks and the
elimination plan, handed to each target's printer."""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable, Sequence, TypeVar

import numpy as np
import sympy as sp

from symid.codegen.flat import Flat
from symid.codegen.sparse import Plan, Step

T = TypeVar("T")


@dataclass(frozen=True)
class Block:
    """Straight-line code for a list of outputs.

    Attributes:
        temps: (name, printed expression) of the common subexpressions, in order.
        outputs: (index, printed expression) of every output (zeros included).
    """

    temps: tuple[tuple[str, str], ...]
    outputs: tuple[tuple[int, str], ...]

    def uses(self, name: str) -> bool:
        """Whether an argument (`q`, `qd`, `t`, `p`, `lam`) appears in the code."""
        import re

        texts = [e for _, e in self.temps] + [e for _, e in self.outputs]
        if name != "t":  # `q[` but not the `sq[` of another argument
            token = re.compile(rf"(?<![\w]){re.escape(name)}\[")
            return any(token.search(e) for e in texts)
        return any(has_word(e, "t") for e in texts)


def has_word(text: str, word: str) -> bool:
    import re

    return re.search(rf"(?<![\w\[.]){word}(?![\w\[])", text) is not None


# CSE'd lists by their expressions: a process that builds several solvers of
# one mechanism (the C solve and study builds, their variants with
# sensitivities, set-points or another precision; the numpy module) CSEs each
# kernel they share once. sympy's CSE is deterministic, so a hit is the result
# a new CSE would give; equality is structural (sympy >= 1.13: 1.0 is not 1).
_CSE: OrderedDict[tuple[str, tuple[sp.Expr, ...]], tuple[tuple[tuple[sp.Symbol, sp.Expr], ...],
                                                        tuple[sp.Expr, ...]]] = OrderedDict()
# A small mechanism's kernels fit; a large one's build keeps only its last
# lists alive past their printing (ladder of 256, numpy: 512 held added 5 % to
# the peak; with 64 it is within run-to-run noise).
CSE_HELD = 64  # lists (chunks of at most CHUNK outputs)


def cse(exprs: Sequence[sp.Expr], prefix: str) -> tuple[tuple[tuple[sp.Symbol, sp.Expr], ...], tuple[sp.Expr, ...]]:
    """sympy's CSE of a list, temporaries named prefix0, prefix1, ... (real), in order."""
    key = (prefix, tuple(sp.sympify(e) for e in exprs))  # 1.0 and 1 are one Python key, not one sympy one
    found = _CSE.get(key)
    if found is None:
        temps, reduced = sp.cse(list(key[1]), symbols=sp.numbered_symbols(prefix, real=True), order="none")
        found = _CSE[key] = (tuple(temps), tuple(reduced))
        if len(_CSE) > CSE_HELD:
            _CSE.popitem(last=False)
    else:
        _CSE.move_to_end(key)
    return found


def block(exprs: Sequence[sp.Expr], printer: Callable[[sp.Expr], str], prefix: str = "e",
          offset: int = 0) -> Block:
    """CSE a list of expressions once and print it; outputs numbered from `offset`."""
    temps, reduced = cse(exprs, prefix)
    return Block(
        temps=tuple((str(sym), printer(e)) for sym, e in temps),
        outputs=tuple((offset + k, printer(e)) for k, e in enumerate(reduced)),
    )


# Outputs CSE'd together. Consecutive outputs belong to the same joint or
# body (rows, Jacobian entries and reactions are laid out instance by
# instance), so chunks keep nearly all the sharing while CSE, printing and
# the C compiler work on pieces of bounded size: total cost linear in the
# mechanism's size instead of superlinear.
CHUNK = 48


def blocks(exprs: Sequence[sp.Expr], printer: Callable[[sp.Expr], str], chunk: int = CHUNK) -> list[Block]:
    """`block` over consecutive chunks of the outputs."""
    return [block(exprs[k:k + chunk], printer, offset=k) for k in range(0, len(exprs), chunk)]


@dataclass(frozen=True)
class Reduced:
    """One chunk after CSE, before printing: print it with any printer."""

    temps: tuple[tuple[sp.Symbol, sp.Expr], ...]
    outputs: tuple[sp.Expr, ...]
    offset: int

    def printed(self, printer: Callable[[sp.Expr], str]) -> Block:
        return Block(tuple((str(s), printer(e)) for s, e in self.temps),
                     tuple((self.offset + k, printer(e)) for k, e in enumerate(self.outputs)))


def reduce(exprs: Sequence[sp.Expr], chunk: int = CHUNK) -> list[Reduced]:
    """CSE consecutive chunks once, for printing in several dialects."""
    out = []
    for k in range(0, len(exprs), chunk):
        temps, reduced = cse(exprs[k:k + chunk], "e")
        out.append(Reduced(temps, reduced, k))
    return out


def chunked(items: Sequence[T], weights: Sequence[int], limit: int = 400) -> list[list[T]]:
    """Consecutive groups of items whose weights add up to at most `limit` (at least one item each)."""
    out: list[list[T]] = []
    total = limit
    for item, w in zip(items, weights):
        if total + w > limit:
            out.append([])
            total = 0
        out[-1].append(item)
        total += w
    return out


def above(plan: Plan) -> dict[int, list[Step]]:
    """Per column: the earlier steps whose U row has an entry in it."""
    out: dict[int, list[Step]] = {}
    for st in plan.steps:
        for c in st.right:
            out.setdefault(c, []).append(st)
    return out


def lu_steps(plan: Plan) -> list[dict[str, object]]:
    """The elimination steps as factor-array slots, for the NumPy printer:
    pivot, column entries for the threshold test, multipliers with their
    updates, and the L, U and U-transposed entries the solves read. (The C
    printer reads the same plan through `sparse.fold`, which also knows the
    values fixed at generation time.)"""
    slots = plan.slots
    up = above(plan)
    return [{
        "row": st.row, "col": st.col, "pivot": slots[(st.row, st.col)],
        "column": [slots[(r, st.col)] for r in st.below],
        "mults": [{"slot": slots[(r, st.col)], "updates": [(slots[(r, c)], slots[(st.row, c)]) for c in st.right]}
                  for r in st.below],
        "below": [(r, slots[(r, st.col)]) for r in st.below],
        "right": [(c, slots[(st.row, c)]) for c in st.right],
        "above": [(prev.row, slots[(prev.row, st.col)]) for prev in up.get(st.col, [])],
    } for st in plan.steps]


def sample_jacobian(flat: Flat, q: np.ndarray, t: float, p: np.ndarray) -> np.ndarray:
    """Phi_q as a dense matrix at one configuration (for the pivot choice)."""
    syms = [sp.Symbol(f"q[{k}]", real=True) for k in range(flat.ng)]
    psyms = [sp.Symbol(f"p[{k}]", real=True) for k in range(len(flat.params))]
    fn = sp.lambdify([syms, sp.Symbol("t", real=True), psyms], [e for _, _, e in flat.jac], [np])
    values = np.array(fn(list(q), t, list(p)), dtype=float).reshape(-1)
    out = np.zeros((flat.nc, flat.ng))
    for (r, c, _), v in zip(flat.jac, values):
        out[r, c] = v
    return out
