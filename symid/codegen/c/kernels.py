"""The C solver's kernels: one function per quantity (phi, phi_q, nu, ...)
as CSE'd chunks of printed statements, with the body angles' sines and
cosines computed once per configuration and shared (`tr`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import sympy as sp

from symid.codegen.c import loops as c_loops
from symid.codegen.c.loops import Loops
from symid.codegen.c.printer import Printer
from symid.codegen.emit import Block, blocks

_PRINTER = Printer({"math_macros": {}})


def ccode(expr: sp.Expr) -> str:
    return _PRINTER.doprint(expr)


def trig_map(ng: int) -> dict[sp.Expr, sp.Symbol]:
    """sin and cos of every body angle -> tr[2b], tr[2b + 1]: computed once per
    configuration and shared by Phi, Phi_q, gamma, Q^A and the reactions."""
    out: dict[sp.Expr, sp.Symbol] = {}
    for b in range(ng // 3):
        angle = sp.Symbol(f"q[{3 * b + 2}]", real=True)
        out[sp.sin(angle)] = sp.Symbol(f"tr[{2 * b}]", real=True)
        out[sp.cos(angle)] = sp.Symbol(f"tr[{2 * b + 1}]", real=True)
    return out


@dataclass(frozen=True)
class Chunk:
    """One function's worth of a kernel's statements, and the arguments it leaves unread."""

    block: Block
    unused: list[str]


@dataclass(frozen=True)
class Kernel:
    """One generated function (templates: `functions`, `sens.kernels`).

    Attributes:
        signature: the kernel's C parameters (`tr` after the first where it reads q).
        public_signature: the exported function's, without `tr`.
        call: the kernel's arguments, as its public wrapper passes them.
        loops: the looped parts' kernels (c.loops), the outputs they cover.
    """

    name: str
    signature: str
    public_signature: str
    chunks: list[Chunk]
    trig: bool
    call: str
    loops: list[dict[str, Any]]


Make = Callable[..., Kernel]


def function(name: str, args: list[tuple[str, str]], exprs: list[sp.Expr],
             trig: dict[sp.Expr, sp.Symbol], printer: Callable[[sp.Expr], str] = ccode,
             real: str = "double", loops: Loops | None = None) -> Kernel:
    """One generated function: a kernel taking the angles' sines and cosines
    precomputed (`tr`), and the public signature without them; with `loops`,
    the outputs they cover are written by looped kernels (loops.j2)."""
    with_trig = any(a == "q" for _, a in args)
    kernel_args = args[:1] + [(f"const {real} *", "tr")] + args[1:] if with_trig else args
    mapped = [e.xreplace(trig) for e in exprs] if with_trig else list(exprs)
    looped = loops.kernels(name, [a for _, a in kernel_args], printer, real) if loops else []
    codes: list[Block] = (c_loops.remaining(mapped, loops.covered(name), printer) if loops and looped
                          else blocks(mapped, printer))

    def sig(items: list[tuple[str, str]]) -> str:
        return ", ".join([f"{ctype} {a}" for ctype, a in items] + [f"{real} *out"])

    chunks = [Chunk(code, [a for _, a in kernel_args if not code.uses(a)]) for code in codes]
    return Kernel(name, sig(kernel_args), sig(args), chunks, with_trig,
                  ", ".join([a for _, a in kernel_args] + ["out"]), looped)
