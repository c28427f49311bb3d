"""`symid derive TYPE|FILE [--latex]`: show a derivation readably (see `symid.show`)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("derive", help="show Phi, the Phi_q blocks, nu, gamma and the reactions of a "
                       "constraint type, or the assembled system of a mechanism file")
    p.add_argument("subject", metavar="TYPE|FILE", help="a constraint type (revolute, gear, ...) or a mechanism file")
    p.add_argument("--latex", action="store_true", help="print LaTeX instead of Unicode")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="variant choice of a type, e.g. coordinate=phi for coordinate_driver")
    p.add_argument("--expanded", action="store_true",
                   help="a type in body-frame components instead of s_i, a_i, d (the notes' notation)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from symid.constraints import TYPES
    from symid.errors import InputError
    from symid.show import derive_mechanism, derive_type

    options = {}
    for pair in args.option:
        key, sep, value = pair.partition("=")
        if not sep:
            raise InputError(f"--option {pair}: expected KEY=VALUE")
        options[key.strip()] = value.strip()
    if args.subject in TYPES:
        shown = derive_type(args.subject, options, expanded=args.expanded)
    elif args.subject.endswith(".toml") or Path(args.subject).is_file():
        if options or args.expanded:
            raise InputError("--option and --expanded apply to a constraint type, not to a mechanism file")
        shown = derive_mechanism(args.subject)
    else:
        raise InputError(f"derive: {args.subject!r} is neither a constraint type nor a mechanism file "
                         f"(types: {', '.join(sorted(TYPES))})")
    print(shown.latex() if args.latex else shown.text(), end="\n" if args.latex else "")
    return 0
