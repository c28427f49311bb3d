"""The sizes a mechanism file and a run may have, each refused up front
(exit 2, naming the limit and the count) rather than found by exhausting the
machine. The README lists them.
"""

MAX_FILE_BYTES = 16 * 1024 * 1024
# Every name becomes part of a file name (`<name>.csv`, `<name>_solver.c`) or a C
# identifier (`<name>_default_params`, `<body>_x`): 64 characters keep both well
# inside the file systems' 255 bytes and what C compilers must distinguish.
MAX_NAME_LENGTH = 64
# Sizes that bound the memory of a run: the dense checks of Phi_q (ng x ng
# doubles) and the sympy work grow with them; 10^4 bodies once grew to 19 GB.
# The largest benchmark (a ladder of 256 four-bars: 513 bodies, ng 1539) peaks at 404 MB;
# dense terms grow as ng^2, so 1000 bodies should stay near 1.5 GB (estimated, not measured).
MAX_BODIES = 1000
MAX_CONSTRAINTS = 4000
MAX_FORCES = 4000
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
