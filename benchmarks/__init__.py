"""symid's benchmarks: one harness (`python -m benchmarks CASE`, run.py), its
cases (cases/), and what they share: mechanisms with exact answers
(ladder.py, systems.py), baselines written without symid (baselines.py,
casadi_*.py) and callgrind's drivers (callgrind.py). docs/benchmarks.md says
how to run them."""
