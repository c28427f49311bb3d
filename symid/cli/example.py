"""`symid example`: the path of a bundled example, or their list."""

from __future__ import annotations

import argparse

from symid.errors import InputError


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    ex = sub.add_parser("example", help="print the path of a bundled example (no name: list them)",
                        description="Print the path of a bundled example mechanism file.",
                        epilog="examples:\n  symid example                  # list the examples\n"
                               "  cp \"$(symid example four_bar)\" my_linkage.toml   # start your own")
    ex.add_argument("name", nargs="?", metavar="NAME", help="an example's name; omit to list them")
    ex.set_defaults(run=cmd_example, file="example")


def cmd_example(args: argparse.Namespace) -> int:
    from symid import api

    if args.name is None:
        print("\n".join(api.examples()))
        return 0
    try:
        print(api.example(args.name))
    except FileNotFoundError as exc:
        raise InputError(str(exc).strip('"')) from None
    return 0
