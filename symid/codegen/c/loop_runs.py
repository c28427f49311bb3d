"""A looped kernel's members as runs (c_lu_runs.segments): where the
members' bodies, rows, factor slots and reaction slots step by fixed
strides over a period of members, and their constants' numbers repeat with
it, the loop reads no table: a period's members are written out with their
indices as `base + stride * g` and their constants computed once, before
the loop. The statements per member are the tabled loop's (templates/c/
loops.j2), so the values are bitwise its; a slot or reaction a member does
not have is left out at generation instead of tested at run time.
"""

from __future__ import annotations

import re
from typing import Any

from symid.codegen.c.loops import Part, _terms
from symid.codegen.c.lu_runs import Op, Run, segments

PMAX = 8          # longest period looked for, in members
LITERAL_MAX = 8   # members outside runs past which the tables stay


def member_ops(part: Part, t: dict[str, Any]) -> list[Op]:
    """Per member: its kind (which slots and reactions it lacks) and its
    numbers (bodies, first row, slots, first reaction slot, then the
    numbers of its varying constants, part.coef flattened)."""
    nr, ns = t["nroles"], t["nslots"]
    ops: list[Op] = []
    for m in range(t["n"]):
        slots = t["slots"][m * ns:(m + 1) * ns]
        kind = repr(([k < 0 for k in slots], t["reactions"][m] < 0))
        coef = [c for row in part.coef[m] for c in row]
        ops.append((kind, (*t["bodies"][m * nr:(m + 1) * nr], t["rows"][m], *slots, t["reactions"][m], *coef)))
    return ops


def _index(base: float, stride: float) -> str:
    if stride == 0:
        return str(base)
    return f"{base} + {stride} * g" if stride > 0 else f"{base} - {-stride} * g"


def _number(base: float, stride: float, real: str) -> str:
    """A constant's number at period g: base + stride * g in floating point,
    which run_lines has checked gives the table's number exactly."""
    if stride == 0:
        return repr(base)
    return f"({base!r} + {stride!r} * ({real})g)"


def _exact(run: Run, first: int, ops: list[Op], skip: int) -> bool:
    """Whether base + stride * r, rounded as C rounds it, is each member's
    number (skip: the indices before the numbers)."""
    p = len(run.body)
    return all(base + stride * float(r) == ops[first + r * p + j][1][skip + q]
               for j, ((_, ints), strides) in enumerate(zip(run.body, run.strides))
               for q, (base, stride) in enumerate(zip(ints[skip:], strides[skip:])) for r in range(run.count))


def _constant(part: Part, j: int, terms: list[int], coef: list[str]) -> str:
    """Constant j as the tabled loop computes it (c_loops._term), its numbers
    the given texts (coef: the member's numbers, part.coef flattened)."""
    v, nb = part.varying.index(j), len(part.basis)
    return " + ".join(coef[v * nb + i] if part.basis[i] == 1 else f"{coef[v * nb + i]} * B{i}"
                      for i in terms) or "0.0"


def _member(k: dict[str, Any], t: dict[str, Any], ints: tuple[float, ...], strides: tuple[float, ...],
            consts: dict[int, str], real: str) -> list[str]:
    """One member's block: its indices, constants, temporaries and outputs."""
    nr, ns = t["nroles"], t["nslots"]
    idx = [_index(int(b), int(d)) for b, d in zip(ints[:nr + ns + 2], strides)]
    row, slots, reac = idx[nr], idx[nr + 1:nr + 1 + ns], idx[nr + 1 + ns]
    out = [f"const int b{r} = {idx[r]};" for r in range(nr)] + [f"(void)b{r};" for r in range(nr)]
    if k["rows"]:
        out += [f"const int r0 = {row};", "(void)r0;"]
    if k["reactions"]:
        out += [f"const int rx = {reac};", "(void)rx;"]
    out += [f"const {real} c{j} = {name};" for j, name in consts.items()]
    out += [f"const {real} {tmp} = {e};" for tmp, e in k["temps"]]
    for o in k["outputs"]:
        guard, target = o["guard"] or "", o["target"]
        slot = re.search(r"slot\[(\d+)\]", target)
        if slot:
            if ints[nr + 1 + int(slot.group(1))] < 0:
                continue
            target = target.replace(slot.group(0), slots[int(slot.group(1))])
        if guard.startswith("rx") and ints[nr + 1 + ns] < 0:
            continue
        out.append(f"{target} = {o['value']};")
    return ["{"] + ["    " + line for line in out] + ["}"]


def run_lines(part: Part, t: dict[str, Any], k: dict[str, Any], real: str) -> list[str] | None:
    """The kernel's loop as runs of members (None: too few of the members
    repeat, or a number does not step exactly: the tabled loop is kept)."""
    ops = member_ops(part, t)
    segs = segments(ops, pmax=PMAX)
    skip = t["nroles"] + t["nslots"] + 2
    if sum(1 for s in segs if not isinstance(s, Run)) > LITERAL_MAX:
        return None
    terms = {j: _terms(part, part.varying.index(j)) for j, _ in k["constants"]}
    lines: list[str] = []
    m = 0
    for s, seg in enumerate(segs):
        if isinstance(seg, Run):
            if not _exact(seg, m, ops, skip):
                return None
            consts: list[dict[int, str]] = []
            for p, ((_, ints), strides) in enumerate(zip(seg.body, seg.strides)):
                coef = [_number(b, d, real) for b, d in zip(ints[skip:], strides[skip:])]
                names = {}
                for j in terms:  # the same at every period: computed once, before the loop
                    names[j] = _constant(part, j, terms[j], coef)
                    if "g" not in names[j]:
                        lines.append(f"const {real} c{j}_{s}_{p} = {names[j]};")
                        names[j] = f"c{j}_{s}_{p}"
                consts.append(names)
            lines.append(f"for (g = 0; g < {seg.count}; ++g) {{")
            for p, ((_, ints), strides) in enumerate(zip(seg.body, seg.strides)):
                lines += ["    " + line for line in _member(k, t, ints, strides, consts[p], real)]
            lines.append("}")
            m += seg.count * len(seg.body)
        else:
            coef = [repr(c) for c in seg[1][skip:]]
            lines += _member(k, t, seg[1], (0,) * len(seg[1]), {j: _constant(part, j, terms[j], coef) for j in terms},
                             real)
            m += 1
    return lines
