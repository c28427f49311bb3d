"""`python -m benchmarks CASE [--smoke] [--out DIR]`: see benchmarks/run.py."""

from benchmarks.run import entry

raise SystemExit(entry())
