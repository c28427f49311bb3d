"""The C solver's memory, stated once: the trajectory state a caller keeps
between calls, the twelve work vectors, and the workspace's sizes.

The templates print the offsets from here (the numbers in the code), the
header states the state's as `<NAME>_STATE_<PART>` macros, and the build
writes them to the solver's `meta.json`, from which the Python hand-back
(`symid.backends.c_backend`) reads them: nothing else recomputes them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

from symid.codegen import friction
from symid.codegen.c import fallback
from symid.codegen.model import CodeModel


@dataclass(frozen=True)
class Slot:
    """One named part of a vector of reals: `size` reals from `offset`."""

    name: str
    offset: int
    size: int
    about: str


@dataclass(frozen=True)
class Vector:
    """Named consecutive parts of one vector of reals."""

    slots: tuple[Slot, ...]

    @classmethod
    def of(cls, parts: tuple[tuple[str, int, str], ...]) -> "Vector":
        """The parts (name, size, about) laid end to end from 0."""
        slots, offset = [], 0
        for name, size, about in parts:
            slots.append(Slot(name, offset, size, about))
            offset += size
        return cls(tuple(slots))

    @property
    def size(self) -> int:
        return sum(s.size for s in self.slots)

    def __getitem__(self, name: str) -> Slot:
        for s in self.slots:
            if s.name == name:
                return s
        raise KeyError(name)

    def __iter__(self) -> Iterator[Slot]:
        return iter(self.slots)

    def at(self, name: str) -> int:
        """The offset of part `name`."""
        return self[name].offset

    def to_json(self) -> dict[str, list[int]]:
        """name -> [offset, size], as the solver's meta.json keeps it."""
        return {s.name: [s.offset, s.size] for s in self.slots}


# The trajectory state (STATE reals), in order. Statics has no rates: qd,
# qdd and m3 are unused and m1, m2 hold the two positions before q.
STATE_PARTS = (
    ("q", "q of the last instant solved (before the first call: the initial guess)"),
    ("qd", "its qdot"),
    ("qdd", "its qddot"),
    ("m1", "the acceleration one instant before (statics: the position)"),
    ("m2", "two instants before"),
    ("m3", "three instants before (statics: unused)"),
    ("scale", "per coordinate, 1 / its scale in the jump check (0: unset)"),
    ("rscale", "per constraint row, its norm in those scales for the conditioning screen (0: unset)"),
)


# The count of instants solved is two reals, each a whole number: the rest
# and the whole multiples of COUNT_CARRY (2^24, where a float stops counting
# by ones). Single precision carries the rest into the second once it
# reaches COUNT_CARRY, so both stay exact (past 2^24 instants, 4.6 h at
# 1 kHz, a single real would stop advancing); double keeps the whole count
# in the first (exact to 2^53) and the second at 0. The count is their sum.
COUNT_CARRY = 1 << 24


def state_layout(ng: int) -> Vector:
    """The trajectory state: eight vectors of NG reals, then the count of
    instants solved (two reals, last: the rest, the multiples of 2^24)."""
    return Vector.of(tuple((name, ng, about) for name, about in STATE_PARTS)
                     + (("count", 2, "instants solved with this state so far, as the sum of its two reals: "
                         "below 2^24 and whole multiples of 2^24 (before the first call: 0, 0)"),))


# The work vectors (each STRIDE reals, after the Phi_q values, the factors
# and the fallback's room), in order: the name of each is its main use.
VECTORS = (
    ("r", "the Newton residual; scratch: a refinement's residual, the estimate's x, statics' masses"),
    ("dq", "the Newton step; scratch: a refinement's correction, the estimate's z"),
    ("y", "the forward solves' intermediate"),
    ("b", "a right-hand side"),
    ("qn", "the instant's q, where the row does not hold it"),
    ("qdn", "its qdot, where the row does not hold it (instant: where not asked for)"),
    ("qddn", "its qddot, likewise"),
    ("lam", "its multipliers, likewise"),
    ("reac", "its reactions, likewise"),
    ("tr", "the sines and cosines of the body angles"),
    ("base", "per body the angle its sines and cosines are rotated from, and theirs (trig_near)"),
    ("kept", "the guess a call was given (back in q if the call fails)"),
)


def vectors() -> Vector:
    """The work vectors by index (offset k: the k-th vector, `<NAME>_VEC(work, k)`)."""
    return Vector.of(tuple((name, 1, about) for name, about in VECTORS))


def stride(model: CodeModel) -> int:
    """Reals per work vector: the longest of q, the rows and the reactions."""
    f = model.flat
    return max(f.ng, f.nc, len(f.reactions), 1)


# Past this many coordinates the solver has no dense fallback: its NG^2
# reals (76 MB at the ladder of 512) would dwarf the sparse factors; a
# configuration the fixed pivots do not serve is factored again by a sparse
# LU with pivoting in a workspace of bounded size (fallback.py,
# templates/c/sparse_fallback.j2).
DENSE_LIMIT = 400


def dense_fallback(model: CodeModel) -> bool:
    return model.flat.ng <= DENSE_LIMIT


def work_size(model: CodeModel) -> int:
    """Reals of workspace a solver call needs before the prepared parameters
    (the context's `work` adds them): Phi_q's values, the sparse factors, the
    pivoting fallback (dense up to DENSE_LIMIT coordinates, sparse past
    it), the work vectors and the friction solve's."""
    f = model.flat
    room = f.ng * f.ng if dense_fallback(model) else fallback.work(model.plan, f.ng)
    return (len(f.jac) + model.plan.size + room + len(VECTORS) * stride(model)
            + friction.work(model.layout, f.options))


def state_size(model: CodeModel) -> int:
    """Reals of trajectory state (state_layout)."""
    return state_layout(model.flat.ng).size
