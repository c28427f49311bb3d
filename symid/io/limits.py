"""The sizes a mechanism file and a run may have, each refused up front
(exit 2, naming the limit and the count) rather than found by exhausting the
machine. The README lists them.
"""

MAX_FILE_BYTES = 16 * 1024 * 1024
# Every name becomes part of a file name (`<name>.csv`, `<name>_solver.c`) or a C
# identifier (`<name>_default_params`, `<body>_x`): 64 characters keep both well
# inside the file systems' 255 bytes and what C compilers must distinguish.
MAX_NAME_LENGTH = 64
# A run's memory is estimated from what it will use, per backend and analysis,
# and refused above SYMID_MEMORY_LIMIT (symid.backends.footprint): the ladder of
# 2048 four-bars (4097 bodies) is cheap on the C backend, and the numpy backend's
# module of 10^4 bodies is not (2.3 GB). These counts bound only what is done before
# any estimate can be: the reader's own objects (about 13 kB per body measured,
# 26 MB for the 4097 of that ladder, its sympy symbols included), so 20000 bodies
# read within about 0.3 GB and a few seconds.
MAX_BODIES = 20_000
MAX_CONSTRAINTS = 80_000
MAX_FORCES = 80_000
MAX_PARAMETERS = 100_000
MAX_STEPS = 10_000_000  # instants of one run: the summary keeps a few columns of each in memory
MAX_VARIANTS = 1_000_000  # a study's variants: a results table of a million rows, tens of MB
# What a study or a run may hold in memory as values (doubles): 2^27, 1 GiB
# (`symid.output.results.check_table_size`, `symid.study.run.check_memory`).
MAX_HELD_VALUES = 2**27
# Option ranges past which a number means nothing to a run (symid.cli.options;
# an option that overrides a file's key takes what the key takes: --t0, --tol):
MAX_WORKERS = 1024  # threads of one sweep
MAX_ITERATIONS = 1_000_000  # optimizer iterations
MAX_BENCH_INSTANTS = 10**9  # instants timed by bench (it repeats the grid; --budget ends it)
MAX_BUDGET_S = 86_400.0  # a bench's time budget: one day
MAX_SEED = 2**64 - 1  # a sample's seed: kept as an unsigned 64-bit number
