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
