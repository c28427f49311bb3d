"""`symid generate`: write a mechanism's generated solver for one target."""

from __future__ import annotations

import argparse
from pathlib import Path

from symid.cli.options import add_set, set_values


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("generate", help="write the generated solver of a mechanism (c, numpy, casadi, fmu)",
                       description="Write a mechanism's generated solver, to use without symid.",
                       epilog='examples:\n  symid generate "$(symid example slider_crank)" --target c -o sc/\n'
                              "  symid generate --examples -o generated   # refresh the committed copies")
    p.add_argument("file", nargs="?", help="mechanism file (omit with --examples)")
    p.add_argument("--target", choices=("c", "numpy", "casadi", "fmu"), action="append",
                   help="target (repeatable; default with --examples: c, numpy, casadi); fmu: an FMI 2.0 "
                        "model-exchange FMU of the set-point entry, compiled with the system's C compiler")
    p.add_argument("-o", "--output", help="folder (default: <name>_<target>; with --examples: generated)")
    p.add_argument("--examples", action="store_true",
                   help="regenerate every bundled example into OUTPUT/<example>/<target>/")
    p.add_argument("--precision", choices=("double", "single"), default="double",
                   help="C target: the floating type of every argument and table (single: float, for an FPU "
                        "without double; its accuracy: docs/c-export.md, symid help c-export)")
    p.add_argument("--sensitivity", metavar="NAME[,NAME...]",
                   help="C target: end each row with the exact derivatives d(COLUMN)/d(NAME) by these base "
                        "parameters (columns outer, parameters inner); default: none, the code as without")
    p.add_argument("--sensitivity-of", metavar="COLUMN[,COLUMN...]",
                   help="the columns differentiated (default: the drivers' efforts and the reaction columns)")
    p.add_argument("--force", action="store_true",
                   help="replace files in the folder that symid did not generate (default: refuse, naming "
                        "the first, nothing written); either way the folder is written whole or not at all")
    add_set(p, "override a parameter's default value in the generated code (repeatable)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from symid import api
    from symid.errors import InputError

    if args.precision != "double" and args.target != ["c"]:
        raise InputError(f"generate: --precision {args.precision} applies to --target c only")
    if args.examples and (args.sensitivity is not None or args.sensitivity_of is not None):
        raise InputError("generate: --sensitivity applies to one FILE, not to --examples")
    if args.examples:
        out = Path(args.output or "generated")
        targets = tuple(args.target or ("c", "numpy", "casadi"))
        for path in api.generate_examples(out, targets, force=args.force):
            print(path)
        return 0
    if not args.file or not args.target:
        raise InputError("generate: give FILE and --target c|numpy|casadi|fmu (or --examples), "
                         "e.g. symid generate crank.toml --target c")
    study_mech = api.load_mechanism(args.file, set_values(args.set, args.file))
    for target in args.target:
        out = Path(args.output) if args.output else Path(f"{study_mech.name}_{target}")
        for path in api.generate(study_mech, target, out, precision=args.precision,
                                 sensitivity=args.sensitivity, sensitivity_of=args.sensitivity_of,
                                 force=args.force):
            print(path)
    return 0

