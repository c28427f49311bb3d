"""What a run will hold in memory, estimated before any work, and the limit
it is refused against (exit 2, naming the resource, the estimate and the
limit): the file's counts say little, since a chain of 2049 bodies takes
180 MiB on the C backend (its setup is linear) and 530 MiB on numpy (its
module).

The estimate is a sum of three parts, each fitted to peak resident sizes
measured with `/usr/bin/time -v symid bench` on the ladder of
`benchmarks/ladder.py` (64, 256 and 1024 four-bars, ng 387 to 6147; 2048
for C):

- the process: Python, numpy, sympy and symid imported (`BASE_MB`);
- the setup per coordinate (`Capabilities.setup_kb`): deriving, the generated
  code held in memory, the compiler's or CasADi's own work on it;
- the dense checks: Phi_q as an nc x ng matrix of doubles, in
  `DENSE_COPIES` copies at once (the matrix, its equilibrated copy, the LU
  factors, the temporaries of the scaling), wherever the rank analysis of
  redundant rows, or the Python loop of a small mechanism, factors it
  (`dense_checks`; from `SPARSE_MIN` coordinates on both are sparse).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

from symid import backends
from symid.errors import InputError
from symid.numeric.stability import SPARSE_MIN

if TYPE_CHECKING:
    from symid.symbolic.assemble import Layout

MB = 2**20
# The limit without SYMID_MEMORY_LIMIT: a run the estimate puts above 2 GiB is
# refused (a laptop's share; 10^4 bodies on the Python loop once grew to 19 GB).
DEFAULT_LIMIT_MB = 2048
LIMIT_VARIABLE = "SYMID_MEMORY_LIMIT"
BASE_MB = 100.0  # measured: 98 MiB for the C bench of the ladder of 64, its setup's share subtracted
# Each backend's setup per coordinate is its `Capabilities.setup_kb`, a slope
# fitted to peak MiB of `symid bench` on the ladder at ng 387, 1539 and 6147
# (rounded up): numpy 128, 185, 527 (71 kB: the code model's sympy trees, the
# printed module and CPython's compiler on its largest function, which
# `numpy_backend.compile_module` compiles alone; 80 declared; 186, 428, 1396
# when the module was compiled in one piece), the reference backend the
# default's 220, casadi 131, 330 at ng 1539 (100 kB: its functions' expression
# graphs; 110 declared), c 99, 106, 176 and 299 at ng 12291 (17 kB; 18 declared; gcc's peak
# counts when larger than Python's: it compiles a loop per constraint family).
DENSE_COPIES = 5


@dataclass(frozen=True)
class Footprint:
    """An estimate of a run's peak memory, in MiB, and its parts.

    Attributes:
        setup_mb: the process and the backend's setup; dense_mb: the dense checks.
        dense: what the dense checks are for ("" when none runs).
    """

    setup_mb: float
    dense_mb: float
    dense: str

    @property
    def total_mb(self) -> float:
        return self.setup_mb + self.dense_mb


def dense_checks(layout: Layout, backend: str) -> str:
    """What factors Phi_q densely in this run ("" when nothing does), below
    `SPARSE_MIN` coordinates only (from there on Phi_q is sparse, its rank
    analysis too: `symid.numeric.sparse_rank`): the rank analysis of more rows
    than coordinates (the redundancy report, on every backend), and the
    Python loop of a backend without a compiled loop."""
    if layout.ng >= SPARSE_MIN:
        return ""
    if layout.nc > layout.ng:
        return "the rank analysis of the redundant rows"
    if not backends.capabilities(backend).compiled_loop:
        return "the Python loop's factorizations of Phi_q"
    return ""


def estimate(layout: Layout, backend: str) -> Footprint:
    """The peak memory a run of `layout` on `backend` should reach (MiB)."""
    ng, nc = layout.ng, layout.nc
    setup = BASE_MB + backends.capabilities(backend).setup_kb * ng / 1024
    dense = dense_checks(layout, backend)
    dense_mb = DENSE_COPIES * 8.0 * nc * max(nc, ng) / MB if dense else 0.0
    return Footprint(setup, dense_mb, dense)


def limit_mb() -> float:
    """The limit in MiB: SYMID_MEMORY_LIMIT (a number of MiB, or with a unit:
    1500M, 4G), else DEFAULT_LIMIT_MB.

    Raises:
        InputError: a value that is not a positive size.
    """
    text = os.environ.get(LIMIT_VARIABLE, "").strip()
    if not text:
        return float(DEFAULT_LIMIT_MB)
    scale = {"M": 1.0, "G": 1024.0}.get(text[-1:].upper())
    try:
        value = float(text[:-1] if scale else text) * (scale or 1.0)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise InputError(f"{LIMIT_VARIABLE}={text!r}: not a memory size (a number of MiB, or 1500M, 4G)")
    return value


def require_within(layout: Layout, backend: str) -> Footprint:
    """The estimate, after refusing a run whose estimate is above the limit.

    Raises:
        InputError: one line naming the file, the resource (memory), the
            estimate, the limit and how to change it.
    """
    need, limit = estimate(layout, backend), limit_mb()
    if need.total_mb <= limit:
        return need
    mech = layout.mechanism
    parts = f"{need.setup_mb:.0f} MiB to set up the {backend} backend"
    if need.dense:
        parts += f" and {need.dense_mb:.0f} MiB for {need.dense} ({layout.nc} x {layout.ng} dense)"
    fits = sorted((estimate(layout, other).total_mb, other) for other in backends.names())
    hint = f"; --backend {fits[0][1]} needs about {fits[0][0]:.0f} MiB" if fits[0][0] <= limit else ""
    raise InputError(f"{mech.source}: memory: a run of {len(mech.bodies)} bodies (ng {layout.ng}) needs about "
                     f"{need.total_mb:.0f} MiB ({parts}), more than the {limit:.0f} MiB allowed "
                     f"({LIMIT_VARIABLE} sets it){hint}")


__all__ = ["DEFAULT_LIMIT_MB", "Footprint", "LIMIT_VARIABLE", "dense_checks", "estimate", "limit_mb",
           "require_within"]
