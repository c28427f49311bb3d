"""The LU as runs of straight-line code: where the elimination repeats with
a period (a chain's bays), one period's statements are emitted once, in a
loop whose indices step by fixed strides. Two sources: the folded
straight-line code (c_lu.lu_chunks, `rolled`: a step's statements with the
known values folded are one statement here), and the index tables
(c_lu_tables, `lu_runs`), used where the folded code does not roll.

A table-driven step loads its indices from memory (three or four per two
flops) and pays a loop per step of one or two entries; a run's statement
has its indices in the code (`y[1026 + 4 * r]`), so the compiler keeps them
as induction variables. The statements, and their order, are exactly those
of the tabled loops (templates/c/sparse_lu_tables.j2), so the factors and
solutions are bitwise theirs. The code's size is that of the periods and of
the statements outside any run, which LITERAL_MAX bounds (past it the
tables are used): it does not grow with the length of a periodic chain.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Sequence

PMAX = 64          # longest period looked for, in statements
MIN_REPEATS = 4    # fewer periods: the statements are emitted one by one
LITERAL_MAX = 2000  # statements outside runs past which the tables stay

Op = tuple[str, tuple[float, ...]]  # (C text with {0}, {1}... for its indices, the indices)


@dataclass(frozen=True)
class Run:
    """count periods of body; period r's indices are base + r * stride."""

    body: tuple[Op, ...]
    strides: tuple[tuple[float, ...], ...]
    count: int


Segment = Run | Op


def _diff(a: Op, b: Op) -> tuple[float, ...] | None:
    """b's indices minus a's, where the two are the same statement."""
    if a[0] != b[0]:
        return None
    return tuple(y - x for x, y in zip(a[1], b[1]))


def _repeats(ops: Sequence[Op], i: int, p: int) -> tuple[int, tuple[tuple[float, ...], ...]]:
    """How many periods of length p repeat from ops[i] with fixed strides."""
    n = len(ops)
    if i + 2 * p > n:
        return 1, ()
    strides = []
    for j in range(p):
        d = _diff(ops[i + j], ops[i + p + j])
        if d is None:
            return 1, ()
        strides.append(d)
    r = 2
    while i + (r + 1) * p <= n:
        base = i + r * p
        if any(_diff(ops[base - p + j], ops[base + j]) != strides[j] for j in range(p)):
            break
        r += 1
    return r, tuple(strides)


def segments(ops: Sequence[Op], pmax: int = PMAX, min_repeats: int = MIN_REPEATS) -> list[Segment]:
    """ops as runs (greedy: at each statement the period covering the most
    statements, the shortest of equals) and single statements, in order."""
    out: list[Segment] = []
    i, n = 0, len(ops)
    while i < n:
        best: tuple[int, int, tuple[tuple[float, ...], ...]] = (0, 0, ())
        for p in range(1, min(pmax, (n - i) // min_repeats) + 1):
            if best[1] and p % best[1] == 0:
                continue  # a multiple of a period found covers no more
            r, strides = _repeats(ops, i, p)
            if r >= min_repeats and r * p > best[0]:
                best = (r * p, p, strides)
        if best[0]:
            covered, p, strides = best
            out.append(Run(tuple(ops[i:i + p]), strides, covered // p))
            i += covered
        else:
            out.append(ops[i])
            i += 1
    return out


def literal_count(segs: Sequence[Segment]) -> int:
    return sum(1 for s in segs if not isinstance(s, Run))


def _index(base: float, stride: float) -> str:
    if stride == 0:
        return str(base)
    return f"{base} + {stride} * r" if stride > 0 else f"{base} - {-stride} * r"


def lines(segs: Sequence[Segment]) -> list[str]:
    """C statements of the segments (a run: a loop over r, declared by the caller)."""
    out: list[str] = []
    for s in segs:
        if isinstance(s, Run):
            out.append(f"for (r = 0; r < {s.count}; ++r) {{")
            for (text, base), stride in zip(s.body, s.strides):
                out += ["    " + line for line in text.format(*map(_index, base, stride)).splitlines()]
            out.append("}")
        else:
            out += s[0].format(*s[1]).splitlines()
    return out


def _factor_ops(t: dict[str, Any], fabs: str, P: str, f: str) -> list[Op]:
    """One statement per step: the tabled factor loop's body for its entries."""
    ops: list[Op] = []
    bp, up = t["below_ptr"], t["update_ptr"]
    for k in range(t["steps"]):
        below = t["below_slot"][bp[k]:bp[k + 1]]
        upd = [(t["update"][u], t["upd_a"][u], t["upd_b"][u]) for u in range(up[k], up[k + 1])]
        nb = len(below)
        text = [f"piv = lu[{{0}}]; cm = {fabs}(piv);"]
        text += [f"cm = {P}_MAX(cm, {fabs}(lu[{{{1 + i}}}]));" for i in range(nb)]
        text.append(f"if (!({fabs}(piv) >= ({P}_THRESHOLD * cm)) || (piv == 0.0{f})) {{{{ return 1; }}}}")
        text.append("lu[{0}] = 1.0" + f + " / piv; piv = lu[{0}];")  # no assignment in an expression (13.4)
        text += [f"lu[{{{1 + i}}}] *= piv;" for i in range(nb)]
        for j in range(len(upd)):
            a = 1 + nb + 3 * j
            text.append(f"lu[{{{a}}}] -= lu[{{{a + 1}}}] * lu[{{{a + 2}}}];")
        ops.append(("\n".join(text), (t["piv"][k], *below, *(i for u in upd for i in u))))
    return ops


def _ops(t: dict[str, Any], multipliers: bool, fabs: str, P: str, f: str) -> dict[str, list[Op]]:
    """Each pass of the tabled LU as statements, in the tables' order."""
    nb, nr, steps = t["n_below"], t["n_right"], t["steps"]
    out: dict[str, list[Op]] = {
        "factor": _factor_ops(t, fabs, P, f),
        "forward": [("y[{0}] -= lu[{1}] * y[{2}];", (t["below_row"][i], t["below_slot"][i], t["below_src"][i]))
                    for i in range(nb)],
        "back": [("y[{0}] -= lu[{1}] * (y[{2}] * lu[{3}]);", (t["bk_dst"][i], t["bk_slot"][i], t["bk_src"][i],
                                                            t["bk_piv"][i])) for i in range(nr)],
        "scale": [("x[{0}] = y[{1}] * lu[{2}];", (t["col"][k], t["row"][k], t["piv"][k])) for k in range(steps)],
    }
    if multipliers:
        out["t_init"] = [("x[{0}] = b[{1}];", (t["row"][k], t["col"][k])) for k in range(steps)]
        out["t_forward"] = [("x[{0}] -= lu[{1}] * (x[{2}] * lu[{3}]);", (t["tf_dst"][i], t["tf_slot"][i],
                                                                         t["tf_src"][i], t["tf_piv"][i]))
                            for i in range(t["n_above"])]
        out["t_scale"] = [("x[{0}] *= lu[{1}];", (t["row"][k], t["piv"][k])) for k in range(steps)]
        out["t_back"] = [("x[{0}] -= lu[{1}] * x[{2}];", (t["tb_dst"][i], t["tb_slot"][i], t["tb_src"][i]))
                         for i in range(nb)]
    return out


def lu_runs(t: dict[str, Any], multipliers: bool, fabs: str, P: str, f: str) -> dict[str, Any] | None:
    """Per pass of the LU, its C lines as runs; None where the statements
    outside runs pass LITERAL_MAX (the tables are then shorter code)."""
    passes = {name: segments(ops) for name, ops in _ops(t, multipliers, fabs, P, f).items()}
    if sum(literal_count(s) for s in passes.values()) > LITERAL_MAX:
        return None
    out: dict[str, Any] = {name: lines(segs) for name, segs in passes.items()}
    out["updates"] = len(t["update"]) if t["update_ptr"][-1] else 0
    out["runs"] = sum(1 for segs in passes.values() for s in segs if isinstance(s, Run))
    return out


_BRACKET = re.compile(r"\[(\d+)\]")


def _step_op(lines_: list[str]) -> Op:
    """A step's statements as one statement: its indices (the numbers in
    brackets) taken out; any other number (a folded known value) stays in
    its text, so a run repeats it only where it is the same."""
    text = "\n".join(lines_).replace("{", "{{").replace("}", "}}")
    ints = tuple(int(k) for k in _BRACKET.findall(text))
    counter = iter(range(len(ints)))
    return _BRACKET.sub(lambda m: f"[{{{next(counter)}}}]", text), ints


def rolled(passes: dict[str, Any]) -> dict[str, Any] | None:
    """The straight-line LU's passes (c_lu.lu_chunks, known values folded)
    as one function each of runs, where the steps repeat: the same
    statements in the same order, so bitwise the same factors and
    solutions. None where nothing repeats or the statements outside runs
    pass LITERAL_MAX."""
    out = dict(passes, rolled=True)
    literal, runs = 0, 0
    for key, steps in passes["step_lines"].items():
        segs = segments([_step_op(ls) for ls in steps])
        literal += literal_count(segs)
        runs += len(segs) - literal_count(segs)
        body = lines(segs)
        if not body:
            out[key] = []
            continue
        code = "\n".join(body)
        has_runs = any(isinstance(s, Run) for s in segs)
        out[key] = [{"lines": (["int r;"] if has_runs else []) + body, "lu": "lu[" in code,
                     "piv": bool(re.search(r"\bpiv\b", code)), "cm": bool(re.search(r"\bcm\b", code))}]
    return out if runs and literal <= LITERAL_MAX else None
