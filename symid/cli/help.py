"""`symid help [TOPIC]`: the mechanism file's manual and the other shipped pages."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("help", help="print the manual: the file format, a type's keys, or a docs page",
                       description="Print symid's documentation, shipped with the package.",
                       epilog="examples:\n  symid help format      # the mechanism file, every key\n"
                              "  symid help revolute    # one type: keys, defaults, columns\n"
                              "  symid help claims      # the claim-file format of symid verify")
    p.add_argument("topic", nargs="?", metavar="TOPIC",
                   help="format, a docs page (command-line, studies, c-export, controller, ...) or a constraint or force type; "
                        "omit to list them all")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from symid.tools import manual
    from symid.errors import InputError

    try:
        print(manual.text(args.topic), end="")
    except LookupError as exc:
        raise InputError(f"help: {exc.args[0]}") from None
    return 0
