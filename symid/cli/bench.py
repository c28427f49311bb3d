"""`symid bench`: time one mechanism on one backend (setup, one instant, residual)."""

from __future__ import annotations

import argparse
import json

from symid.cli.options import TOL, Number, add_file, add_set, set_values
from symid.io.limits import MAX_BENCH_INSTANTS, MAX_BUDGET_S


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("bench", help="time a mechanism on one backend: setup, microseconds per instant, residual",
                       description="Time one mechanism on one backend: setup (derive, generate, compile), "
                                   "microseconds per instant and the largest residual.",
                       epilog='examples:\n  symid bench "$(symid example slider_crank)"\n'
                              "  symid bench crank.toml --backend numpy --instants 10000 --json")
    add_file(p, "the mechanism file (TOML)")
    p.add_argument("--backend", default="c", help="backend to time (default: c)")
    p.add_argument("--instants", type=Number(True, 1, MAX_BENCH_INSTANTS), help="instants to time (default: the file's steps; more repeat the "
                                                "file's run from q0)")
    p.add_argument("--tol", type=TOL, help="Newton tolerance (default: the file's)")
    p.add_argument("--budget", type=Number(False, 0.0, MAX_BUDGET_S, lo_open=True), default=60.0, metavar="SECONDS",
                   help="stop timing after this long (default: 60)")
    p.add_argument("--warm", action="store_true", help="use the cache of generated solvers (default: an empty "
                                                       "one, so setup is timed cold)")
    add_set(p)
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from symid.tools.bench import bench, text
    from symid.errors import EXIT_ANALYSIS

    result = bench(args.file, args.backend, instants=args.instants, tol=args.tol, cold=not args.warm,
                   budget_s=args.budget, set_values=set_values(args.set))
    result.pop("kept", None)
    print(json.dumps(result, indent=1) if args.json else text(result))
    return EXIT_ANALYSIS if result.get("error") else 0
