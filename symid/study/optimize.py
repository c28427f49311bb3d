"""Design optimization: minimize one figure of a study over bounded base
parameters, with bounds on other figures, by scipy.optimize on exact gradients.

Each point the optimizer visits is one solve of the whole run with the exact
sensitivities of the columns the figures are read from; `symid.study.gradients`
turns them into the figures' gradients. The solve itself is passed in (a
`Solver`): the study layer sits below the API that computes sensitivities.
The parameters are scaled to [0, 1] over their bounds and the objective by its
value at the start, so one tolerance serves every unit.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from symid.backends import Array
from symid.errors import AnalysisError, InputError
from symid.model.mechanism import Mechanism, parameter_symbol
from symid.model.params import parameter_values
from symid.output.results import Results, columns
from symid.study import sizing_limits
from symid.study.design import check_names, check_span, finite_number
from symid.study.figures import figure_names
from symid.study.gradients import drive_margins, figure_gradients, has_gradient, needed_columns
from symid.study.inertials import checker
from symid.study.sizing_gradients import MARGINS
from symid.study.slow import figures_of, study_analysis, with_values
from symid.symbolic.assemble import assemble
from symid.text import number

# (mechanism, parameters to differentiate by, columns to differentiate) -> the run
# with `d(C)/d(P)` columns appended (none asked: the plain run).
Solver = Callable[[Mechanism, Sequence[str], Sequence[str]], Results]
_LIMIT = re.compile(r"\s*([^<>=\s]+)\s*(<=|>=)\s*(.+)\Z")


@dataclass(frozen=True)
class Bound:
    """`--vary NAME=LO:HI`: a base parameter and its interval (LO < HI)."""

    name: str
    lo: float
    hi: float


@dataclass(frozen=True)
class Limit:
    """`--subject-to FIGURE<=VALUE` (sense "<=") or `FIGURE>=VALUE` (">=")."""

    figure: str
    sense: str
    value: float

    def text(self) -> str:
        return f"{self.figure}{self.sense}{self.value:g}"


def parse_vary(specs: Sequence[str]) -> list[Bound]:
    """`--vary NAME=LO:HI ...` (at least one; LO < HI)."""
    if not specs:
        raise InputError("--vary: name at least one parameter to vary, as NAME=LO:HI")
    out = []
    for spec in specs:
        name, sep, rest = spec.partition("=")
        parts = rest.split(":")
        if not sep or not name.strip() or len(parts) != 2:
            raise InputError(f"--vary {spec}: expected NAME=LO:HI")
        lo = finite_number(parts[0], f"--vary {spec}: LO")
        hi = finite_number(parts[1], f"--vary {spec}: HI")
        if lo >= hi:
            raise InputError(f"--vary {spec}: LO {parts[0].strip()} must be less than HI {parts[1].strip()}")
        check_span(lo, hi, f"--vary {spec}")  # the optimizer works on (p - LO) / (HI - LO)
        out.append(Bound(name.strip(), lo, hi))
    return out


def parse_limits(specs: Sequence[str]) -> list[Limit]:
    """`--subject-to FIGURE<=VALUE|FIGURE>=VALUE ...`."""
    out = []
    for spec in specs:
        m = _LIMIT.match(spec)
        if m is None:
            raise InputError(f"--subject-to {spec}: expected FIGURE<=VALUE or FIGURE>=VALUE")
        out.append(Limit(m.group(1), m.group(2), finite_number(m.group(3), f"--subject-to {spec}: VALUE")))
    return out


def check(mechanism: Mechanism, objective: str, bounds: Sequence[Bound], limits: Sequence[Limit]) -> None:
    """Refuse, before any solve, a figure the study does not have or that has
    no gradient, a parameter that is not a base one, and a start outside its bounds.

    The start is the file's value (after `--set`): one outside [LO, HI] is
    refused, not clipped, so the run starts where the file says or nowhere.
    """
    source = mechanism.source
    names = figure_names(mechanism)
    for option, figure in [("--minimize", objective)] + [(f"--subject-to {lim.text()}", lim.figure)
                                                        for lim in limits]:
        if figure not in names:
            raise InputError(f"{source}: {option}: no figure {figure!r} (figures: {', '.join(names) or 'none'})"
                             + sizing_limits.hint(figure))
    sizing_limits.check(objective, limits, source)
    for option, figure in [("--minimize", objective)] + [(f"--subject-to {lim.text()}", lim.figure)
                                                        for lim in limits if not lim.figure.endswith(".fits")]:
        if not has_gradient(figure):
            raise InputError(f"{source}: {option}: {figure!r} is an instant of the time grid and has no gradient: "
                             "optimize effort_peak, effort_rms, power_peak or force_peak (a drive's motor_rms "
                             "or motor_peak, a bearing's L10_h)")
    check_names([b.name for b in bounds], mechanism.parameters, source, "--vary")
    values = parameter_values(mechanism.parameters)
    for b in bounds:
        start = values[parameter_symbol(b.name)]
        if not b.lo <= start <= b.hi:
            raise InputError(f"{source}: --vary {b.name}={b.lo:g}:{b.hi:g}: the start {b.name} = {start:.17g} "
                             f"(the file's value) is outside [{b.lo:g}, {b.hi:g}]; widen the bounds or start "
                             f"inside them with --set {b.name}=VALUE")


@dataclass
class Point:
    """One visited point: parameter values, figures (figure_names order) and
    their gradients (figures x parameters; None without sensitivities); per
    driver of a `D.fits>=1` limit, its verdict's margins and their gradients."""

    p: Array
    figures: Array
    gradients: Array | None
    margins: dict[str, tuple[Array, Array | None]] = field(default_factory=dict)


@dataclass
class Problem:
    """The optimization of one figure of `mechanism` over `bounds`.

    Attributes:
        solver: solves a variant (see `Solver`); exact: use its sensitivities
            (False: scipy's finite differences of the figures, for comparison).
        evaluations: solves so far; history: (figure, gradient norm) per iteration.
    """

    mechanism: Mechanism
    objective: str
    bounds: list[Bound]
    limits: list[Limit]
    solver: Solver
    exact: bool = True
    evaluations: int = 0
    history: list[tuple[float, float]] = field(default_factory=list)
    _cache: dict[bytes, Point] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.mechanism = study_analysis(self.mechanism)
        self.names = [b.name for b in self.bounds]
        self.lo = np.array([b.lo for b in self.bounds])
        self.width = np.array([b.hi - b.lo for b in self.bounds])
        values = parameter_values(self.mechanism.parameters)
        self.start = np.array([values[parameter_symbol(n)] for n in self.names])
        self.figures = list(figure_names(self.mechanism))
        self._negative = checker(self.mechanism, self.names)  # lambdified once, asked at every point
        self.columns = needed_columns(self.mechanism, columns(assemble(self.mechanism), self.mechanism.analysis))
        self.fits = [lim.figure[: -len(".fits")] for lim in self.limits if lim.figure.endswith(".fits")]

    def params(self, u: Array) -> Array:
        """Parameter values of the scaled point u in [0, 1]^n."""
        return self.lo + np.clip(u, 0.0, 1.0) * self.width

    def at(self, u: Array) -> Point:
        """Solve (once per point) and differentiate the variant at u.

        Raises:
            AnalysisError: the variant does not solve to t1: the figure over
                the instants before, the time and the reason.
        """
        p = self.params(np.asarray(u, dtype=float))
        key = p.tobytes()
        if key in self._cache:
            return self._cache[key]
        variant = with_values(self.mechanism, self.names, [float(v) for v in p])
        where = ", ".join(f"{n} = {v:.17g}" for n, v in zip(self.names, p))
        negative = self._negative(p.reshape(1, -1))
        if negative is not None:  # refused in a file: never reported as an optimum
            raise AnalysisError(f"the optimizer visited {where}, which cannot be solved: {negative[1]}, "
                                f"which must not be negative; narrow the --vary bounds")
        if np.array_equal(p, self.start):
            where += " (the start)"
        self.evaluations += 1
        with np.errstate(all="ignore"):  # a value not finite is named below, once, not warned about
            try:
                results = self.solver(variant, self.names if self.exact else (), self.columns if self.exact else ())
            except ValueError as exc:  # a derived parameter not finite: the variant has no value at all
                raise AnalysisError(f"the optimizer visited {where}, which cannot be solved: "
                                    f"{' '.join(map(str, exc.args))}") from None
            figures = figures_of(variant, results)
            if results.error is not None:
                value = figures[self.figures.index(self.objective)]
                when = number(results.error.time) if results.error.time is not None else "?"
                raise AnalysisError(f"the optimizer visited {where}, which does not solve: {self.objective} = "
                                    f"{value:.6g} over the instants before t = {when}: "
                                    f"{results.error}") from None
            grads = figure_gradients(variant, results, self.names) if self.exact else None
            margins = drive_margins(variant, results, self.names if self.exact else (), self.fits)
        self._check_finite(where, figures, grads, margins)
        point = Point(p, figures, grads, margins)
        self._cache[key] = point
        return point

    def _check_finite(self, where: str, figures: Array, grads: Array | None,
                      margins: dict[str, tuple[Array, Array | None]]) -> None:
        """Refuse a point where a figure SLSQP uses (the objective, each limit's) or
        its gradient is not finite: SLSQP would go on from NaN and end with a
        message about something else ("Inequality constraints incompatible").

        Raises:
            AnalysisError: naming the point, the figure and the parameters.
        """
        for driver, (values, slopes) in margins.items():
            for m, check in enumerate(MARGINS):
                bad = [] if slopes is None else [f"{n} ({g})" for n, g in zip(self.names, slopes[m])
                                                  if not math.isfinite(g)]
                if not math.isfinite(values[m]):
                    raise AnalysisError(f"the optimizer visited {where}: the {check} margin of {driver}.fits>=1 "
                                        f"is {values[m]} there, not a number SLSQP can bound")
                if bad:
                    raise AnalysisError(f"the optimizer visited {where}: the {check} margin of {driver}.fits>=1 "
                                        f"has no gradient by {', '.join(bad)}: an envelope whose points depend on a "
                                        "parameter varied has none")
        for figure in dict.fromkeys([self.objective, *(lim.figure for lim in self.limits
                                                       if not lim.figure.endswith(".fits"))]):
            k = self.figures.index(figure)
            if not math.isfinite(figures[k]):
                raise AnalysisError(f"the optimizer visited {where}: {figure} = {figures[k]} there, not a "
                                    "number SLSQP can minimize or bound; narrow the --vary bounds")
            if grads is None:
                continue
            bad = [f"{n} ({g})" for n, g in zip(self.names, grads[k]) if not math.isfinite(g)]
            if bad:
                raise AnalysisError(f"the optimizer visited {where}: the gradient of {figure} = {figures[k]:.6g} "
                                    f"by {', '.join(bad)} is not finite there, so SLSQP cannot step from it; "
                                    "start and bound the parameters where the figure is differentiable")

    def value(self, u: Array, figure: str) -> float:
        return float(self.at(u).figures[self.figures.index(figure)])

    def margin(self, u: Array, driver: str, m: int) -> float:
        """The m-th margin of the drive on `driver` (`Verdict.margins`)."""
        return float(self.at(u).margins[driver][0][m])

    def margin_gradient(self, u: Array, driver: str, m: int) -> Array:
        """d(margin)/du (scaled parameters)."""
        slopes = self.at(u).margins[driver][1]
        assert slopes is not None, "gradients are asked only of an exact problem"
        return slopes[m] * self.width

    def gradient(self, u: Array, figure: str) -> Array:
        """d(figure)/du (scaled parameters)."""
        grads = self.at(u).gradients
        assert grads is not None, "gradients are asked only of an exact problem"
        return grads[self.figures.index(figure)] * self.width


@dataclass(frozen=True)
class Outcome:
    """Where the optimizer ended: parameters, objective, the start's objective,
    success and scipy's message, iterations and solves; per parameter, the
    bound it ended on ("lower", "upper" or "": inside its range)."""

    names: tuple[str, ...]
    p: Array
    value: float
    start_value: float
    success: bool
    message: str
    iterations: int
    evaluations: int
    bound: tuple[str, ...] = ()
    unmet: tuple[str, ...] = ()

    def where(self) -> str:
        """"a = 0.1 (on its lower bound), b = 2.5": the optimum, a bound said where it holds one."""
        return ", ".join(f"{n} = {v:.10g}" + (f" (on its {side} bound)" if side else "")
                         for n, v, side in itertools.zip_longest(self.names, self.p, self.bound, fillvalue=""))


# SLSQP puts a variable whose bound is active exactly on it (it projects onto
# the box); an interior optimum within 1e-9 of the range of a bound is on it
# for any design purpose
ON_BOUND = 1e-9


def _bounds_held(u: Array) -> tuple[str, ...]:
    """Per scaled parameter u in [0, 1], "lower", "upper" or ""."""
    return tuple("lower" if x <= ON_BOUND else "upper" if x >= 1 - ON_BOUND else "" for x in u)


def run(problem: Problem, report: Callable[[int, float, float], None] | None = None, maxiter: int = 100,
        ftol: float = 1e-14) -> Outcome:
    """Minimize by SLSQP (bounded, with the limits as inequality constraints).

    Args:
        report: called after each iteration with (iteration, figure, norm of
            its gradient in the parameters' units; NaN without exact gradients).
        ftol: SLSQP's tolerance on the objective scaled by its start value.
    """
    from scipy.optimize import minimize

    u0 = (problem.start - problem.lo) / problem.width
    f0 = problem.value(u0, problem.objective)
    scale = abs(f0) if f0 != 0 and math.isfinite(f0) else 1.0
    exact = problem.exact

    def fun(u: Array) -> float:
        return problem.value(u, problem.objective) / scale

    def jac(u: Array) -> Array:
        return problem.gradient(u, problem.objective) / scale

    constraints = []
    for driver in problem.fits:  # the drive fits: each check of its verdict as a margin >= 0
        for m in range(len(MARGINS)):
            c: dict[str, object] = {"type": "ineq", "fun": lambda u, d=driver, m=m: problem.margin(u, d, m)}
            if exact:
                c["jac"] = lambda u, d=driver, m=m: problem.margin_gradient(u, d, m)
            constraints.append(c)
    for lim in problem.limits:
        if lim.figure.endswith(".fits"):
            continue
        sign = 1.0 if lim.sense == "<=" else -1.0
        size = abs(lim.value) if lim.value != 0 else 1.0
        c = {"type": "ineq",
             "fun": lambda u, lim=lim, s=sign, z=size: s * (lim.value - problem.value(u, lim.figure)) / z}
        if exact:
            c["jac"] = lambda u, lim=lim, s=sign, z=size: -s * problem.gradient(u, lim.figure) / z
        constraints.append(c)
    count = [0]

    def callback(u: Array) -> None:
        count[0] += 1
        value = problem.value(u, problem.objective)
        grads = problem.at(u).gradients
        norm = float(np.linalg.norm(grads[problem.figures.index(problem.objective)])) if grads is not None \
            else float("nan")
        problem.history.append((value, norm))
        if report is not None:
            report(count[0], value, norm)

    result = minimize(fun, u0, jac=jac if exact else None, method="SLSQP", bounds=[(0.0, 1.0)] * len(u0),
                      constraints=constraints, callback=callback, options={"maxiter": maxiter, "ftol": ftol})
    p = problem.params(result.x)
    return Outcome(tuple(problem.names), p, problem.value(result.x, problem.objective), f0, bool(result.success),
                   str(result.message), int(result.nit), problem.evaluations, _bounds_held(np.clip(result.x, 0, 1)),
                   _unmet(problem, result.x))


# a limit is unmet where the optimizer stopped when its figure passes the value
# by more than this fraction of |value| (of 1 for a value 0): far above SLSQP's
# own feasibility slack at ftol 1e-14, far below a limit that cannot be met
UNMET = 1e-6


def _unmet(problem: Problem, u: Array) -> tuple[str, ...]:
    """The limits not met at scaled point u, each as "FIGURE = x (<= VALUE)"."""
    unmet = []
    for lim in problem.limits:
        value = problem.value(u, lim.figure)
        if lim.figure.endswith(".fits"):  # the verdict itself, as `symid size` gives it
            if value != 1:
                unmet.append(sizing_limits.unmet(lim.figure, value, problem.at(u).margins))
            continue
        excess = value - lim.value if lim.sense == "<=" else lim.value - value
        if not excess <= UNMET * (abs(lim.value) if lim.value != 0 else 1.0):
            unmet.append(f"{lim.figure} = {value:.6g} ({lim.sense} {lim.value:g})")
    return tuple(unmet)


def snippet(outcome: Outcome, objective: str, source: str) -> str:
    """The optimized values as a `[parameters]` TOML snippet (17 significant digits)."""
    lines = [f"# symid optimize {source}: {objective} = {outcome.value:.10g} (start {outcome.start_value:.10g})",
             "[parameters]"]
    lines += [f"{n} = {v!r}" + (f"  # on its {side} bound" if side else "")
              for n, v, side in itertools.zip_longest(outcome.names, map(float, outcome.p), outcome.bound,
                                                      fillvalue="")]
    return "\n".join(lines) + "\n"
