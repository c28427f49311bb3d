"""`symid derive TYPE|FILE [--latex]`: show a derivation readably (see `symid.tools.show`)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("derive", help="show Phi, the Phi_q blocks, nu, gamma and the reactions of a "
                       "constraint type, or the assembled system of a mechanism file",
                       description="Show a derivation the way the lecture notes write it (symbols: "
                                   "symid help symbols).",
                       epilog="examples:\n  symid derive revolute_revolute\n"
                              "  symid derive coordinate_driver --option coordinate=phi --latex\n"
                              '  symid derive "$(symid example four_bar)"')
    p.add_argument("subject", metavar="TYPE|FILE", help="a constraint type (revolute, gear, ...) or a mechanism file")
    p.add_argument("--latex", action="store_true", help="print LaTeX instead of Unicode")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="variant choice of a type, e.g. coordinate=phi for coordinate_driver")
    p.add_argument("--expanded", action="store_true",
                   help="a type in body-frame components instead of s_i, a_i, d (the notes' notation)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from symid.symbolic.constraints import TYPES
    from symid.errors import InputError
    from symid.tools.show import check_options, derive_mechanism, derive_type

    options = {}
    for pair in args.option:
        key, sep, value = pair.partition("=")
        if not sep:
            raise InputError(f"--option {pair}: expected KEY=VALUE")
        options[key.strip()] = value.strip()
    if args.subject in TYPES and TYPES[args.subject].shape is not None:  # `type = "expression"`
        raise InputError(f"derive {args.subject}: its rows are written in a mechanism file; derive the file "
                         "(symid derive FILE) to see them, Phi_q, nu, gamma and the reactions")
    if args.subject in TYPES:
        check_options(args.subject, options)
        for key in TYPES[args.subject].keys:  # say how to give a variant choice on this command line
            if key.kind == "choice" and options.get(key.name) not in key.choices:
                given = f"not {options[key.name]!r}; " if key.name in options else ""
                raise InputError(f"derive {args.subject}: option '{key.name}' must be one of "
                                 f"{', '.join(key.choices)} ({given}give it as --option {key.name}="
                                 f"{key.choices[-1]})")
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
