"""The figures of a design study: one row of numbers per variant.

Their names and order are the contract's (`symid sweep`): per driver D in
file order `D.effort_peak D.effort_t_peak D.effort_rms D.power_peak`, then per
constraint C of `[analysis] reactions` (default all) `C.force_peak`; a file
with drives or bearings adds `D.motor_rms D.motor_peak D.fits` per drive and
`C.L10_h` per bearing (`symid.output.sizing`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from symid.errors import AnalysisError

if TYPE_CHECKING:  # the mechanism's module imports sympy: reading a sweep table (symid plot) never needs it
    from symid.model.mechanism import Mechanism

# Why a variant's run stopped (index = code); "ok" when it ran to t1.
STATUS = ("ok", "not_converged", "singular", "jump", "nonfinite")
# The sweep table's last column: per variant the largest condition estimate of
# Phi_q above cond_warn at any instant (where `symid solve --set` warns
# "ill-conditioned"), 0 where none passed it.
COND_COLUMN = "cond_worst"
DRIVER_FIGURES = ("effort_peak", "effort_t_peak", "effort_rms", "power_peak")


def figure_names(mechanism: Mechanism) -> tuple[str, ...]:
    """The figure columns of a study of `mechanism`, in contract order."""
    from symid.model.mechanism import is_driver

    a = mechanism.analysis
    if a.kind == "kinematics":  # no forces solved: no efforts, no reactions
        return ()
    names = [f"{c.name}.{f}" for c in mechanism.constraints if is_driver(c) for f in DRIVER_FIGURES]
    names += [f"{name}.force_peak" for name in mechanism.chosen_reactions]
    if mechanism.sizing:  # drives and bearings (symid help sizing): after the contract's figures
        from symid.output.sizing import figure_names as sizing_names

        names += sizing_names(mechanism)
    return tuple(names)


def cond_of(warnings: list[str]) -> float:
    """The worst condition estimate of a run from its warning lines
    (`Notes.lines`: "... worst 3.2e+09 at t = ..."), 0.0 without one."""
    for line in warnings:
        found = re.search(r"^Phi_q is ill-conditioned: .* worst ([^ ]+) at t = ", line)
        if found:
            return float(found.group(1))
    return 0.0


def status_of(error: AnalysisError | None) -> int:
    """The `STATUS` code of a run's failure (0: it ran to t1), from the
    backends' shared messages (Newton's "Phi is not finite at the guess" is a
    Newton failure)."""
    if error is None:
        return 0
    text = str(error)
    if "assembly mode jump" in text:
        return STATUS.index("jump")
    if "not finite" in text and "Newton did not converge" not in text:
        return STATUS.index("nonfinite")
    if "singular" in text:
        return STATUS.index("singular")
    return STATUS.index("not_converged")


@dataclass(frozen=True)
class Figures:
    """The figures of K variants.

    Attributes:
        names: figure column names, in contract order (`figure_names`).
        values: shape (K, len(names)); a failed variant holds the figures of
            the instants solved before it stopped (NaN when none was).
        status: shape (K,), an index into `STATUS`.
        t_end: shape (K,), the last instant solved (NaN when none was).
        cond: shape (K,), the largest condition estimate above cond_warn
            (`COND_COLUMN`; 0 where no instant passed it; None: zeros).
    """

    names: tuple[str, ...]
    values: np.ndarray
    status: np.ndarray
    t_end: np.ndarray
    cond: np.ndarray | None = None

    def __post_init__(self) -> None:
        k = len(self.status)
        if self.cond is None:
            object.__setattr__(self, "cond", np.zeros(k))
        if self.values.shape != (k, len(self.names)) or self.t_end.shape != (k,) or self.cond.shape != (k,):
            raise ValueError(f"figures of {k} variants: values {self.values.shape}, t_end {self.t_end.shape}")

    @property
    def warned(self) -> np.ndarray:
        """Indices of the variants whose run passed cond_warn somewhere."""
        return np.flatnonzero(np.asarray(self.cond) > 0)

    def __len__(self) -> int:
        return len(self.status)
