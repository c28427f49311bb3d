"""symid's benchmark: symid's backends against hand-written baselines (see run.py)."""
