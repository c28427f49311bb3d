"""What `symid optimize` accepts of the sizing figures (`symid help sizing`):
a drive's verdict `D.fits` only as the bound `D.fits>=1` (the optimizer keeps
each of its checks' margins >= 0, `Verdict.margins`), a bearing's life
`C.L10_h` bounded, not minimized."""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping, Sequence

from symid.errors import InputError
from symid.study.sizing_gradients import MARGINS

if TYPE_CHECKING:
    from symid.backends import Array
    from symid.study.optimize import Limit


def hint(figure: str) -> str:
    """What a sizing figure the file does not have needs."""
    if figure.endswith(".L10_h"):
        return "; a bearing's life needs bearing = { C = ..., p = ... } on its revolute (symid help sizing)"
    if figure.endswith((".motor_rms", ".motor_peak", ".fits")):
        return "; a drive's figures need a [[drive]] on that driver (symid help sizing)"
    return ""


def check(objective: str, limits: Sequence[Limit], source: str) -> None:
    """Refuse minimizing a verdict or a life, and a verdict bounded other than `>=1`."""
    what = objective.rsplit(".", 1)[0]
    if objective.endswith(".fits"):
        raise InputError(f"{source}: --minimize {objective}: a verdict (1 or 0) is not minimized: bound it with "
                         f"--subject-to {objective}>=1 (the drive fits), or minimize {what}.motor_rms")
    if objective.endswith(".L10_h"):
        raise InputError(f"{source}: --minimize {objective}: a life is wanted long, and symid optimize minimizes "
                         f"(maximizing is not in the command line): bound it with --subject-to "
                         f"{objective}>=HOURS and minimize another figure")
    for lim in limits:
        if lim.figure.endswith(".fits") and not (lim.sense == ">=" and lim.value == 1):
            raise InputError(f"{source}: --subject-to {lim.text()}: a verdict (1 or 0) is bounded only as "
                             f"{lim.figure}>=1 (the drive fits: its RMS, peak, speed and envelope checks)")


def unmet(figure: str, value: float, margins: Mapping[str, tuple[Array, object]]) -> str:
    """"D.fits = 0 (>= 1: RMS torque margin -0.02)": the checks that fail."""
    got = margins[figure[: -len(".fits")]][0]
    failed = ", ".join(f"{check} margin {m:.3g}" for check, m in zip(MARGINS, got) if m < 0)
    return f"{figure} = {value:g} (>= 1: {failed or 'within rounding of a rating'})"
