"""`symid sweep`: the figures of many variants of one mechanism, one row each.

The variants come from `--grid`, `--table` or `--sample`; they run in chunks
on this machine's cores or on a Dask scheduler. Ctrl-C (or SIGTERM) writes the
variants finished so far, atomically, and exits 128 + N, as a solve does.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Iterator

from symid.cli.options import Number, add_time_grid, set_values
from symid.io.limits import MAX_SEED, MAX_VARIANTS, MAX_WORKERS
from symid.errors import AnalysisError, InputError, say_kept
from symid.text import plural

SWEEP_EPILOG = """examples:
  symid sweep crank.toml --grid L_rod=0.25:0.4:4 --grid n=2:8:4 --steps 101 --plot
  symid sweep crank.toml --sample 1000 --normal L_rod=0.3,0.001 --uniform m_rod=0.95,1.05 --seed 1 -o mc.parquet
  symid sweep crank.toml --table variants.csv --scheduler tcp://10.0.0.5:8786

Columns: variant, the varied parameters, status, t_end, then per driver D
D.effort_peak D.effort_t_peak D.effort_rms D.power_peak, per constraint C
C.force_peak (symid help format, "Design studies"); with --gradients then
d(FIGURE)/d(P) for every figure and varied parameter (figures outer), exact,
each variant solved on its own with its sensitivities (no batch engine).
exit status: 0 the sweep ran (status says which variants failed), 2 bad input,
3 no variant could be solved."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("sweep", help="solve many variants of a mechanism: peak and RMS efforts, peak forces",
                       description="A design study: the figures of every variant (grid, table or sample) "
                                   "of one mechanism, one row each.", epilog=SWEEP_EPILOG)
    p.add_argument("file", metavar="FILE", help="the mechanism file (TOML; symid help format)")
    p.add_argument("--grid", action="append", default=[], metavar="NAME=LO:HI:N",
                   help="N equally spaced values from LO to HI (repeatable: the product, the last fastest)")
    p.add_argument("--table", metavar="VARIANTS.csv",
                   help="one variant per row, a header row of base parameter names")
    p.add_argument("--sample", type=Number(True, 1, MAX_VARIANTS), metavar="N", help="N random variants (with --normal, --uniform)")
    p.add_argument("--normal", action="append", default=[], metavar="NAME=MEAN,SD",
                   help="with --sample: draw NAME from a normal distribution (repeatable)")
    p.add_argument("--uniform", action="append", default=[], metavar="NAME=LO,HI",
                   help="with --sample: draw NAME uniformly from [LO, HI] (repeatable)")
    p.add_argument("--seed", type=Number(True, 0, MAX_SEED), default=0, metavar="S", help="seed of the sample (numpy default_rng)")
    p.add_argument("-o", "--output", metavar="OUT",
                   help="table to write, .csv or .parquet (default: <name>_sweep.csv in the current folder)")
    p.add_argument("--backend", default="c", metavar="B",
                   help="c (fastest) or numpy; casadi and reference solve variant by variant")
    p.add_argument("--workers", type=Number(True, 1, MAX_WORKERS), metavar="K", help="threads on this machine (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask distributed scheduler")
    p.add_argument("--json", action="store_true",
                   help="print variants, failed, setup_s, solve_s, instants_per_s as JSON on stdout")
    add_time_grid(p, ("inverse_dynamics", "kinematics", "statics"), "variant")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="fix a parameter for every variant (repeatable)")
    p.add_argument("--plot", action="store_true", help="also write PNG plots of the study beside the table")
    p.add_argument("--gradients", action="store_true",
                   help="add d(FIGURE)/d(P) for every figure and varied parameter after the figures: exact, "
                        "each variant solved on its own with its sensitivities (slower than the batch engine)")
    p.set_defaults(run=cmd_sweep)


def _each(counts: Iterator[int]) -> Iterator[None]:
    """One item per finished variant, for the progress bar."""
    for count in counts:
        for _ in range(count):
            yield None


def cmd_sweep(args: argparse.Namespace) -> int:
    from symid import api, progress
    from symid.io.files import beside, check_target, output_format
    from symid.study import design as vary
    from symid.study import inertials
    from symid.study.figures import figure_names
    from symid.study.cluster import ClusterLost
    from symid.study.run import Sweep, check_memory
    from symid.study.table import FORMATS, conditioning_note

    if args.gradients and args.scheduler:
        raise InputError("--gradients runs each variant on this machine (solved on its own with its "
                         "sensitivities): drop --scheduler")
    chosen = vary.of_options(args.grid, args.table, args.sample, args.normal, args.uniform, args.seed)
    fixed = set_values(args.set, args.file)
    both = [n for n in chosen.names if n in fixed]
    if both:
        raise InputError(f"{args.file}: parameter {both[0]!r} is both fixed by --set and varied")
    overrides = {"kind": args.kind, "t0": args.t0, "t1": args.t1, "steps": args.steps, "tol": args.tol}
    with progress.status(f"symid: setting up the {args.backend} backend"):
        progress.stage("reading")
        mech = api.load_mechanism(args.file, fixed, **overrides)
        option = {"grid": "--grid", "table": f"--table {args.table}", "sample": "--sample"}[chosen.kind]
        vary.check_names(chosen.names, mech.parameters, args.file, option)
        inertials.check(mech, chosen.names, chosen.values, option)  # as the reader refuses them in a file
        check_memory(mech, chosen, args.backend, f"{args.file}: {option}", args.gradients)
        out = Path(args.output) if args.output else Path(f"{mech.name}_sweep.csv")
        if output_format(out, FORMATS, "a sweep table") == ".parquet":
            _need_pyarrow()
        check_target(out)
        client = None
        if args.scheduler:
            from symid.study import cluster

            progress.stage(f"connecting to {args.scheduler}")
            client = cluster.connect(args.scheduler)
        if args.gradients:
            sweep = _gradient_sweep(args, mech, chosen)
        else:
            sweep = Sweep(mech, chosen, args.backend, args.workers, client)
        progress.stage("building the solver")
        try:
            sweep.setup()
        except BaseException:
            _close(client)
            raise
    try:
        for _ in progress.bar(_each(sweep.run()), len(chosen), "sweep", unit="variants"):
            pass
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM: keep what is finished, then end as the signal says
        table = sweep.table()
        table.write(out)
        say_kept(exc, f"{out} holds the {plural(len(table), 'variant')} finished before it")
        raise
    except ClusterLost as exc:  # the cluster went away mid-study: keep what is finished, exit 3
        table = sweep.table()
        table.write(out)
        raise ClusterLost(f"{exc}; {out} holds the {plural(len(table), 'variant')} finished before it") from None
    finally:
        _close(client)
    table = sweep.table()
    table.write(out)
    print(f"{out}: {plural(len(table), 'variant')}, {table.failed} failed", file=sys.stderr if args.json else
          sys.stdout)
    warned = conditioning_note(table, mech.analysis.cond_threshold)
    if warned:
        print(f"symid: warning: {warned}", file=sys.stderr)
    if args.json:
        instants = sweep.instants()
        print(json.dumps({"variants": len(table), "failed": table.failed, "setup_s": sweep.setup_s,
                          "solve_s": sweep.solve_s, "instants": instants,
                          "instants_per_s": instants / sweep.solve_s if sweep.solve_s > 0 else None,
                          "backend": args.backend, "output": str(out)}))
    if args.plot:
        from symid.output.sweep_plot import write_all

        shown = len(figure_names(mech))  # the figures, not their gradients
        notes: list[str] = []
        folder, stem = beside(out, f"{mech.name}_sweep")  # not /dev/null_figures.png
        for path in write_all(table.params, table.values, table.figures.names[:shown],
                              table.figures.values[:, :shown], table["status"], folder, stem, chosen.kind, notes):
            print(path, file=sys.stderr if args.json else sys.stdout)
        for note in notes:
            print(f"symid sweep: plot: {note}", file=sys.stderr)
    if len(table) and table.failed == len(table):
        raise AnalysisError(f"{args.file}: no variant could be solved (status of the first: "
                            f"{table['status'][0]}); the table is in {out}")
    return 0


def _gradient_sweep(args: argparse.Namespace, mech: Any, chosen: Any) -> Any:
    """The sweep of `--gradients` (variant by variant on this machine, exact sensitivities)."""
    from symid.study.gradient_sweep import GradientSweep
    from symid.tools.sensitive import solver

    return GradientSweep(mech, chosen, args.backend, solver(args.backend))


def _need_pyarrow() -> None:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        raise InputError("-o .parquet needs pyarrow (python3 -m pip install pyarrow)") from None


def _close(client: Any) -> None:
    if client is not None:
        try:
            client.close()
        except Exception:  # closing a client of a scheduler that went away: nothing left to do
            pass
