"""Tools built on a solved or derived mechanism: `check`, the readable
derivations (`show`), claims checking (`verify`, `subjects`), the benchmark
of one mechanism (`bench`), the run plans of repeated solves (`plan`) and the
manual `symid help` prints (`manual`).

May import `symid.api` and every layer below; never `symid.cli`.
"""
