"""`symid check`: validate a file; report its sizes, rank and conditioning at t0."""

from __future__ import annotations

import argparse

from symid.cli.options import add_file, add_set, set_values
from symid.errors import AnalysisError
from symid.text import number


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    chk = sub.add_parser("check", help="validate a file; report ng, nc, rank and conditioning at q0",
                         description="Read and validate a mechanism file; report its sizes, the rank of "
                                     "Phi_q and its condition at t0.",
                         epilog='examples:\n  symid check "$(symid example four_bar)"\n'
                                "  symid check crank.toml --set L2=0.35")
    add_file(chk)
    add_set(chk)
    chk.set_defaults(run=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    from symid import api
    from symid.tools.check import check

    study = api.prepare(args.file, "reference", set_values(args.set, args.file))
    report = check(study)
    print(report.text())
    if report.singular:
        raise AnalysisError(f"{args.file}: t = {number(study.analysis.t0)}: Phi_q is rank-deficient (rank "
                            f"{report.rank} < {report.ng}); dependent constraints: {', '.join(report.dependent)}")
    return 0
