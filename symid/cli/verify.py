"""`symid verify CLAIMS.toml ...`: check hand derivations (see `symid.tools.verify`).

Exit status 0 when every claim holds, 1 when any does not, 2 for a malformed file.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("verify", help="check hand derivations (claim files) against symid's derivation",
                       description="Check hand derivations against symid's own. "
                                   "Exit status 0: all hold, 1: some do not, 2: a malformed file.",
                       epilog="examples:\n  symid verify homework.toml\n  symid verify --bundled\n"
                              "The claim-file format: symid help claims (docs/claims.md).")
    p.add_argument("files", nargs="*", metavar="CLAIMS.toml",
                   help="claim files (format: docs/claims.md, symid help claims)")
    p.add_argument("--bundled", action="store_true",
                   help="also verify the claim files shipped with symid (the lecture notes' hand results)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from symid.errors import InputError
    from symid.tools.verify import bundled, verify

    files = [*args.files, *(bundled() if args.bundled else [])]
    if not files:
        raise InputError("verify: give a claim file (or --bundled)")
    status = 0
    for path in files:
        report = verify(path)
        print(report.text())
        status = max(status, report.exit_status)
    return status
