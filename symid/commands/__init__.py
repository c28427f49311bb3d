"""Subcommands beyond solve/check/example, one module each.

Each module named in MODULES has `register(sub)`, which adds its parser to
the argparse subparsers and sets `run=` to a function (args) -> exit status.
"""

MODULES: tuple[str, ...] = (
    "symid.commands.plot",
    "symid.commands.generate",
    "symid.commands.derive",
    "symid.commands.verify",
    "symid.commands.bench",
    "symid.commands.help",
)
