"""The command line: `entry.main` parses arguments and hands each
subcommand to its own small module here.

The top layer: it may import everything, and nothing imports it.
"""

from symid.cli.entry import main

__all__ = ["main"]
