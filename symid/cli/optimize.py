"""`symid optimize`: minimize one study figure over bounded base parameters,
by scipy's SLSQP on the exact gradients of the figures (`symid.study.optimize`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from symid.cli.options import Number, add_file, add_set, add_time_grid, set_values
from symid.io.limits import MAX_ITERATIONS
from symid.errors import AnalysisError

if TYPE_CHECKING:  # registering the subcommand imports no sympy
    from symid.model.mechanism import Mechanism
    from symid.study.optimize import Bound

OPTIMIZE_EPILOG = """examples:
  symid optimize "$(symid example slider_crank_counterweight)" --minimize motor.effort_rms \\
      --vary m_cw=1:4 --vary beta_cw=2.5:3.8
  symid optimize crank.toml --minimize motor.effort_rms --vary L_rod=0.25:0.4 \\
      --subject-to crank_pin.force_peak<=800 -o best.toml

Figures: per driver D D.effort_peak D.effort_rms D.power_peak, per constraint
C C.force_peak (as `symid sweep` names them; D.effort_t_peak has no gradient);
with drives and bearings (symid help sizing) D.motor_rms D.motor_peak, a
bearing's C.L10_h as a bound (--subject-to C.L10_h>=20000), and the verdict
only as --subject-to D.fits>=1 (the drive fits: RMS, peak, speed, envelope).
Each iteration prints the figure and the norm of its gradient; the optimum is
written as a [parameters] TOML snippet to paste into the file.
The start is the file's value of each varied parameter (after --set); a start
outside [LO, HI] is refused, not clipped.
exit status: 0 converged, 2 bad input, 3 the optimizer did not converge, or
visited a variant that does not solve (named with its figure, time and reason)."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("optimize", help="minimize a study figure over bounded parameters (exact gradients)",
                       description="Minimize one figure of the run (peak or RMS effort, peak power, peak "
                                   "reaction force) over bounded base parameters, with optional bounds on "
                                   "other figures: scipy SLSQP on the exact sensitivities.",
                       epilog=OPTIMIZE_EPILOG)
    add_file(p)
    p.add_argument("--minimize", required=True, metavar="FIGURE", help="the figure to minimize, e.g. motor.effort_rms")
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LO:HI",
                   help="a base parameter and its bounds, LO < HI (repeatable; at least one)")
    p.add_argument("--subject-to", action="append", default=[], metavar="FIGURE<=VALUE",
                   help="keep a figure below (<=) or above (>=) a value (repeatable)")
    p.add_argument("-o", "--output", metavar="OUT.toml",
                   help="the [parameters] snippet to write (default: <name>_optimized.toml in the current folder)")
    p.add_argument("--backend", default="c", metavar="B",
                   help="c (default: the sensitivities in compiled code), numpy, casadi or reference")
    p.add_argument("--maxiter", type=Number(True, 1, MAX_ITERATIONS), default=100, metavar="N", help="SLSQP iterations at most")
    add_time_grid(p, ("inverse_dynamics", "statics"), "run")
    add_set(p, "set a parameter (repeatable; a varied one: its start)")
    p.set_defaults(run=cmd_optimize)


def cmd_optimize(args: argparse.Namespace) -> int:
    from symid import api
    from symid.io.files import atomic_write, check_target, output_format
    from symid.study import optimize as opt
    from symid.tools.sensitive import solver

    bounds = opt.parse_vary(args.vary)
    limits = opt.parse_limits(args.subject_to)
    overrides = {"kind": args.kind, "t0": args.t0, "t1": args.t1, "steps": args.steps, "tol": args.tol}
    mech = api.load_mechanism(args.file, set_values(args.set, args.file), **overrides)
    opt.check(mech, args.minimize, bounds, limits)
    _check_memory(mech, bounds, args)
    out = Path(args.output) if args.output else Path(f"{mech.name}_optimized.toml")
    output_format(out, (".toml",), "the optimum's [parameters] snippet")
    check_target(out)
    problem = opt.Problem(mech, args.minimize, bounds, limits, solver(args.backend))

    def report(iteration: int, value: float, norm: float) -> None:
        print(f"iteration {iteration}: {args.minimize} = {value:.10g}, |gradient| = {norm:.3g}", flush=True)

    outcome = opt.run(problem, report, maxiter=args.maxiter)
    if not outcome.success and outcome.unmet:  # scipy's message then names its line search, not the cause
        raise AnalysisError(f"{args.file}: the optimizer stopped after {outcome.iterations} iterations "
                            f"({outcome.evaluations} solves) at {outcome.where()} with a limit not met: "
                            f"{', '.join(outcome.unmet)}; the limits may not be met together within the "
                            f"--vary bounds (SLSQP: {outcome.message}); nothing written")
    if not outcome.success:
        raise AnalysisError(f"{args.file}: the optimizer did not converge after {outcome.iterations} iterations "
                            f"({outcome.evaluations} solves): {outcome.message}; nothing written")
    print(f"optimum: {outcome.where()}: {args.minimize} = {outcome.value:.10g} (start {outcome.start_value:.10g}), "
          f"{outcome.iterations} iterations, {outcome.evaluations} solves")
    for lim in limits:
        print(f"  {lim.figure} = {problem.value((outcome.p - problem.lo) / problem.width, lim.figure):.10g} "
              f"({lim.sense} {lim.value:g})")
    with atomic_write(out) as f:
        f.write(opt.snippet(outcome, args.minimize, Path(args.file).name))
    print(out, file=sys.stderr)
    return 0


def _check_memory(mech: Mechanism, bounds: Sequence[Bound], args: argparse.Namespace) -> None:
    """Each point is one variant solved with its sensitivities by every varied
    parameter, its whole table held: refused up front past the study limit."""
    import numpy as np

    from symid.study.design import Variants
    from symid.study.run import check_memory

    point = Variants("table", tuple(b.name for b in bounds), np.zeros((1, len(bounds))))
    check_memory(mech, point, args.backend, f"{args.file}: --vary", gradients=True)
