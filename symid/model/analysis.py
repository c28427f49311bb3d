"""What to compute and when: the `[analysis]` table, plain data without sympy.

Kept apart from `symid.model` so that a run whose solver and plan are cached
(`symid.tools.plan`) reads it without importing sympy; `symid.model` re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

KINDS = ("inverse_dynamics", "kinematics", "statics")
OUTPUT_GROUPS = ("q", "qdot", "qddot", "lambda", "reactions")
KIND_OUTPUTS: Mapping[str, tuple[str, ...]] = {
    "inverse_dynamics": OUTPUT_GROUPS,
    "kinematics": ("q", "qdot", "qddot"),
    "statics": ("q", "lambda", "reactions"),
}
# Columns beyond the contract's groups, written after all of them (see
# docs/analysis-options.md); never on by default.
EXTRA_OUTPUTS = ("cond",)
REDUNDANT_MODES = ("error", "min_norm")
JUMP_MODES = ("error", "warn")
DEFAULT_COND_WARN = 1e6  # forces lose about 2 log10(cond) digits: 4 of 16 left here


@dataclass(frozen=True)
class Analysis:
    """What to compute and when; see the contract's `[analysis]` table."""

    kind: str = "inverse_dynamics"
    t0: float = 0.0
    t1: float = 1.0
    steps: int = 1001
    tol: float = 1e-12
    outputs: tuple[str, ...] | None = None
    reactions: tuple[str, ...] | None = None
    # numerical stability (docs/analysis-options.md); None: not set, the default applies
    cond_warn: float | None = None
    redundant: str = "error"
    assembly_jump: str = "error"

    @property
    def cond_threshold(self) -> float:
        """The condition number above which a run warns."""
        return DEFAULT_COND_WARN if self.cond_warn is None else self.cond_warn

    def extra_outputs(self) -> tuple[str, ...]:
        """The requested columns beyond the contract's groups (`cond`), in order."""
        return tuple(e for e in EXTRA_OUTPUTS if e in (self.outputs or ()))

    def output_groups(self) -> tuple[str, ...]:
        """The output groups to write, in contract order."""
        wanted = self.outputs if self.outputs is not None else KIND_OUTPUTS[self.kind]
        return tuple(g for g in OUTPUT_GROUPS if g in wanted)

    def times(self) -> "list[float]":
        """The output instants t_k = t0 + k (t1 - t0) / (steps - 1)."""
        if self.steps == 1:
            return [self.t0]
        h = (self.t1 - self.t0) / (self.steps - 1)
        return [self.t0 + k * h for k in range(self.steps)]
