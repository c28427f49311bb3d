"""The C sweep's variants side by side in SIMD lanes (templates/c/lanes.j2).

`<name>_sweep` takes its variants in groups of 4 or 2 (WIDTHS), one a lane
of a GCC / clang vector type, in lock-step through the same operations the scalar
sweep does in the same order, so that every figure is bitwise the scalar
one. The kernels are the scalar ones' printed statements with the lane type:
arithmetic needs no change (the compilers allow vector-scalar operands),
libm calls go to helpers that call the same function on each lane, and a
value that depends on the time alone stays scalar until it is stored.
What does not print so (a comparison or a cast inside an expression, a
tabled function) leaves the mechanism with the scalar sweep, as do the
forms the lanes do not cover: single precision, friction, sensitivities,
more than MAX_NG coordinates and a structurally singular Phi_q.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from symid.codegen.c.kernels import Kernel

if TYPE_CHECKING:
    from symid.codegen.c.compose import CContext

# variants a group: four doubles fill an AVX2 register, two an SSE2 one (the
# baseline of x86-64); the code has both and takes AVX2 where the processor
# has it (the cache's code runs on any of its machines: no -march=native).
# Measured (slider-crank grid, one thread, gcc 12): 2 lanes 1.8 x the
# one-by-one sweep; 4 lanes in SSE2 pairs slower than 2 (32-byte vectors
# cross calls in memory); 4 in AVX2 3.1 x. Each width costs compile time
# (gcc -O1 on the lanes, slider-crank: 0.41 s without lanes, 0.80 s with
# both widths, about 0.65 s with AVX2 alone): (4,) leaves a processor
# without AVX2 the one-by-one sweep.
WIDTHS = (2, 4)

# libm functions of one argument, and of two, the lanes call per lane
UNARY = ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "fabs")
BINARY = ("atan2", "pow")

# Coordinates up to which the sweep has lanes. Their code is written out per
# width, and gcc's time on it grows faster than the mechanism: the ladder of
# 4 bays (27 coordinates) compiles in 1.7 s against 0.8 s without lanes, the
# ladder of 12 (75) in 3.7 s against 1.3 s; a cold build pays that before a
# sweep of a few hundred variants gains it back. Every bundled example (at
# most 12 coordinates) has them.
MAX_NG = 30

_CALL = re.compile(r"\b([A-Za-z_]\w*)\(")
_ARRAY = re.compile(r"\b\w+\[")


class Unsupported(Exception):
    """A statement the lanes cannot print bitwise as the scalar code does."""


def _split_call(text: str, start: int) -> tuple[list[str], int]:
    """The top-level arguments of the call whose '(' ends at start, and the index past its ')'."""
    depth, j, begin, args = 1, start, start, []
    while depth:
        if j >= len(text):
            raise Unsupported(text)
        c = text[j]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif c == "," and depth == 1:
            args.append(text[begin:j])
            begin = j + 1
        j += 1
    args.append(text[begin:j - 1])
    return args, j


def _is_lane(plain: str, lane_words: set[str]) -> bool:
    return bool(_ARRAY.search(plain)) or any(re.search(rf"(?<![\w.]){w}(?!\w)", plain) for w in lane_words)


class Converter:
    """Prints scalar C statements with the lane type; `used` collects the
    lane helpers they call."""

    def __init__(self, p: str, P: str) -> None:
        self.p, self.P = p, P
        self.used: set[str] = set()
        self.macros = {f"{P}_MAX": "max", f"{P}_MIN": "min"}

    def expr(self, text: str, lane_words: set[str]) -> tuple[str, bool]:
        """(the expression with lane calls, whether its value is a lane vector)."""
        if "?" in text or "<" in text or ">" in text or "_real)" in text or "(double)" in text:
            raise Unsupported(text)
        out, i, lane = [], 0, False
        while (m := _CALL.search(text, i)) is not None:
            plain = text[i:m.start()]
            lane = lane or _is_lane(plain, lane_words)
            out.append(plain)
            args, i = _split_call(text, m.end())
            name = m.group(1)
            conv = [self.expr(a, lane_words) for a in args]
            fn = self.macros.get(name, name)
            if not any(is_lane for _, is_lane in conv):
                if fn not in UNARY + BINARY and name != f"{self.p}_powi":
                    raise Unsupported(name)
                out.append(f"{name}({', '.join(a for a, _ in conv)})")
                continue
            lane = True
            if name == f"{self.p}_powi":
                fn = "powi"
            elif fn not in UNARY + BINARY + ("max", "min"):
                raise Unsupported(name)
            printed = [a if is_lane or (fn == "powi" and k == 1) else f"@L@_lsplat({a})"
                       for k, (a, is_lane) in enumerate(conv)]
            self.used.add(fn)
            out.append(f"@L@_l{fn}({', '.join(printed)})")
        out.append(text[i:])
        lane = lane or _is_lane(text[i:], lane_words)
        return "".join(out), lane

    def block(self, block: Any, lane_words: set[str]) -> dict[str, Any]:
        """A CSE'd block: temps as (type, name, expr), outputs as (index, expr), each stored as a lane."""
        words = set(lane_words)
        temps = []
        for name, e in block.temps:
            text, lane = self.expr(e, words)
            if lane:
                words.add(name)
            temps.append(("@L@_lane" if lane else f"{self.p}_real", name, text))
        outputs = []
        for k, e in block.outputs:
            text, lane = self.expr(e, words)
            outputs.append((k, text if lane else f"@L@_lsplat({text})"))
        return {"temps": temps, "outputs": outputs}

    def lu_line(self, line: str) -> str:
        """One statement of the straight-line sparse LU (c_lu._factor_lines and the solves)."""
        words = {"piv", "cm"}
        if line.startswith("return 1;"):
            return line
        m = re.fullmatch(r"if \(!\((?P<a>.*) >= \((?P<b>.*)\)\)(?P<z> \|\| \(piv == 0\.0\))?\) \{ return 1; \}", line)
        if m:
            # only the lanes still iterating (act) decide: the others' values are not read
            a, _ = self.expr(m["a"], words)
            b, _ = self.expr(m["b"], words)
            zero = f" || @L@_lany((piv == 0.0) & act)" if m["z"] else ""
            return f"if (!@L@_lall(({a} >= {b}) | ~act){zero}) return 1;"
        m = re.fullmatch(r"(?P<lhs>[\w\[\]]+) (?P<op>[-+*]?=) (?P<rhs>.*);", line)
        if not m:
            raise Unsupported(line)
        rhs, lane = self.expr(m["rhs"], words)
        if not lane:
            rhs = f"@L@_lsplat({rhs})"
        return f"{m['lhs']} {m['op']} {rhs};"


def _signature(p: str, fn: Kernel) -> str:
    """The kernel's signature with the lane type: every array a lane array, t scalar."""
    out = []
    for arg in fn.call.split(", "):
        if arg == "t":
            out.append(f"{p}_real t")
        elif arg == "out":
            out.append("@L@_lane *out")
        else:
            out.append(f"const @L@_lane *{arg}")
    return ", ".join(out)


Converted = dict[str, Any]  # a block with the lane type: "temps" (type, name, expr), "outputs" (index, expr)


@dataclass(frozen=True)
class Lanes:
    """What templates/c/lanes*.j2 need (`lanes`; None: the scalar sweep only).

    Attributes:
        widths: variants per group (WIDTHS).
        functions: per kernel its name, lane signature, call and converted chunks.
        prepare, guess, drive: the prepared pieces', guess's and drivers' blocks, converted.
        factor_chunks .. t_back_chunks: the straight-line LU's passes, converted.
        used: the lane helpers of libm functions the code calls.
        drivers, reactions: the sweep's, their offsets into the multipliers and reactions.
    """

    widths: tuple[int, ...]
    functions: list[dict[str, Any]]
    prepare: list[Converted]
    guess: Converted
    drive: Converted | None
    factor_chunks: list[dict[str, Any]]
    forward_chunks: list[dict[str, Any]]
    back_chunks: list[dict[str, Any]]
    t_forward_chunks: list[dict[str, Any]]
    t_back_chunks: list[dict[str, Any]]
    used: list[str]
    drivers: list[dict[str, Any]]
    reactions: list[dict[str, Any]]


def context(ctx: "CContext") -> Lanes | None:
    """The sweep's variants in lanes for a context (None: the scalar sweep only)."""
    lu, sweep = ctx.lu, ctx.sweep
    if (ctx.precision != "double" or ctx.friction or ctx.sens or ctx.phase.phases or ctx.splines
            or lu.tables or lu.runs or ctx.singular or ctx.loop_tables or sweep.pairs
            or not ctx.velocity or not ctx.dynamics or lu.rolled or ctx.phase.wrap_angles
            or ctx.ng > MAX_NG):
        return None
    p, P = ctx.p, ctx.P
    conv = Converter(p, P)
    try:
        functions = []
        for fn in ctx.functions:
            if fn.loops:
                return None
            chunks = [{"unused": ch.unused, **conv.block(ch.block, set())} for ch in fn.chunks]
            functions.append({"name": fn.name, "signature": _signature(p, fn), "call": fn.call,
                              "chunks": chunks})
        prepare = [conv.block(b, set()) for b in ctx.prepare]
        guess = conv.block(sweep.guess, set())
        drive = conv.block(sweep.drive, set()) if sweep.drive else None
        passes = {key: [{**ch, "lines": [conv.lu_line(line) for line in ch["lines"]]} for ch in getattr(lu, key)]
                  for key in ("factor_chunks", "forward_chunks", "back_chunks", "t_forward_chunks", "t_back_chunks")}
    except Unsupported:
        return None
    offsets = {group: offset for group, _, _, offset in ctx.row_parts}
    lam0, reac0 = offsets.get("lambda", 0), offsets.get("reactions", 0)
    return Lanes(
        widths=WIDTHS, functions=functions, prepare=prepare, guess=guess, drive=drive, **passes,
        used=sorted(conv.used - {"max", "min", "all", "any", "fabs"}),
        # the figures' sources: the multipliers and the reactions, indices into their own vectors
        drivers=[{**d, "lam": d["lam"] - lam0} for d in sweep.drivers],
        reactions=[{**r, "pairs": [off - reac0 for off in r["pairs"]]} for r in sweep.reactions],
    )
