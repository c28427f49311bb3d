"""`symid size FILE [--json] [--plot]`: motors, gear ratios and bearings from the run (docs/sizing.md)."""

from __future__ import annotations

import argparse
import json
import sys

from symid.cli.options import add_file, add_set, set_values


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("size", help="size the file's drives and bearings from its run (exit 4: something does not fit)",
                       description="Solve the file and size every [[drive]] (motor torque and speed through "
                                   "the gear: RMS, peak, speed, envelope, best ratio of a range) and every "
                                   "revolute's bearing (equivalent load, L10 life). Exit 0 when every drive "
                                   "fits, 4 when one does not (the line says what and when).",
                       epilog='examples:\n  symid size "$(symid example slider_crank_sized)"\n'
                              "  symid size press.toml --json\n  symid size press.toml --plot -o plots")
    add_file(p)
    add_set(p)
    p.add_argument("--backend", default="numpy", metavar="B", help="backend solving the run (numpy, c, casadi, reference)")
    p.add_argument("--json", action="store_true", help="print one JSON object: drives and bearings")
    p.add_argument("--plot", action="store_true", help="also write <name>_sizing.png (envelope, trajectory, "
                                                       "RMS point; bearings' loads and lives)")
    p.add_argument("-o", "--output", metavar="DIR", default=".", help="folder of the --plot picture")
    p.set_defaults(run=cmd_size)


def cmd_size(args: argparse.Namespace) -> int:
    from symid import api
    from symid.output import sizing
    from symid.errors import EXIT_DOES_NOT_FIT, InputError

    mech = api.load_mechanism(args.file, set_values(args.set, args.file), **sizing.ANALYSIS)
    if not mech.sizing:
        raise InputError(f"{args.file}: nothing to size: no [[drive]] and no revolute with a bearing "
                         "(symid help sizing)")
    mech = sizing.for_sizing(mech)
    results = api.prepare(mech, args.backend).solve()
    if results.error is not None:  # a part of the cycle sizes nothing: exit 3, naming the instant
        raise results.error
    report = sizing.size(mech, results)
    if args.json:
        print(json.dumps(_nulls(report.json())))
    else:
        print("\n".join(report.lines()))
    if args.plot:
        from symid.output.sizing_plot import write

        print(f"wrote {write(report, mech.name, args.output)}", file=sys.stderr)
    return 0 if report.fits else EXIT_DOES_NOT_FIT


def _nulls(data: dict[str, object]) -> dict[str, object]:
    """An unloaded bearing's infinite life as null (JSON has no infinity)."""
    for b in data["bearings"]:  # type: ignore[attr-defined]
        if b["L10_h"] == float("inf"):
            b["L10_h"] = None
    return data
