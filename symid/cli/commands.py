"""The subcommands, one module each, in the order `symid --help` lists them.

Each module named in MODULES has `register(sub)`, which adds its parser to
the argparse subparsers and sets `run=` to a function (args) -> exit status.
"""

MODULES: tuple[str, ...] = (
    "symid.cli.solve",
    "symid.cli.sweep",
    "symid.cli.optimize",
    "symid.cli.check",
    "symid.cli.size",
    "symid.cli.example",
    "symid.cli.plot",
    "symid.cli.generate",
    "symid.cli.derive",
    "symid.cli.verify",
    "symid.cli.bench",
    "symid.cli.help",
)
