"""The C target: a dependency-free C99 solver (`.h`, `.c`, Makefile) per mechanism.

`context` (compose.py) builds one typed record (`CContext`) from a code model, composed
of a section per part of the templates, each built by its module:

    kernels      the quantity functions (phi, phi_q, ...), CSE'd chunks
    loops,       looped kernels of long chains, as tables or runs
      loop_runs
    lu, lu_runs, the fixed sparse LU: straight-line, rolled, index tables
      lu_tables
    fallback     the sparse pivoting fallback past the dense one's size
    phase        single precision's phases and whole-turn wraps
    checks       the trajectory's finite checks
    sensitivity  parameter sensitivities (opt-in)
    sweep, lanes the batch entry, its variants in SIMD lanes
    describe     the header's names, units, grid and operation counts
    layout       the trajectory state and work vectors, stated once
    printer      SymPy's C printer per real type

`write` renders it (templates/c/solver.c.j2, solver.h.j2, Makefile.j2).
"""

from symid.codegen.c.compose import TEMPLATES, CContext, context, generate, write
from symid.codegen.c.kernels import ccode

NAME = "c"

__all__ = ["NAME", "TEMPLATES", "CContext", "ccode", "context", "generate", "write"]
