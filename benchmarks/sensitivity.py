"""Sensitivities benchmark (issue #15, Python path): what the d(COLUMN)/d(NAME)
columns cost per instant on the shared Python loop, against the same loop
without them, for 1, 3 and all base parameters.

    python -m benchmarks.sensitivity [--example slider_crank] [--instants N] [--repeats R]
                                     [--backend numpy] [--out benchmarks/results]

Measured in one run, so the machine's load shifts both sides alike: the ratio
(with / without) per n_p, and the fitted cost per parameter (the issue's
target for generated C is 1 + 0.3 n_p; this is the Python loop's figure,
which the generated C of `csens` replaces). Setup (the one-time sympy
derivation and lambdify) is reported apart. Prints and writes sensitivity.json.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from symid import api
from symid.model.params import base_names
from symid.numeric.solve import run

ROOT = Path(__file__).resolve().parent.parent


def _best(fn, repeats: int) -> float:  # type: ignore[no-untyped-def]
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return float(best)


def main(argv: list[str] | None = None) -> dict[str, object]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--example", default="slider_crank")
    parser.add_argument("--instants", type=int, default=201)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--backend", default="numpy")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = parser.parse_args(argv)
    path = api.example(args.example)
    names = base_names(api.load_mechanism(path).parameters)
    plain = api.prepare(path, args.backend, steps=args.instants)
    base = _best(lambda: sum(1 for _ in run(plain.evaluator, plain.analysis, plain.q0())), args.repeats)
    figures: dict[str, object] = {"example": args.example, "backend": args.backend, "instants": args.instants,
                                  "plain_us_per_instant": base / args.instants * 1e6, "machine": platform.machine()}
    ratios = {}
    for count in sorted({1, min(3, len(names)), len(names)}):
        start = time.perf_counter()
        study = api.prepare(path, args.backend, steps=args.instants, sensitivity=names[:count])
        list(study.rows())  # the first run derives and lambdifies: setup
        setup = time.perf_counter() - start
        took = _best(lambda: sum(1 for _ in study.rows()), args.repeats)  # noqa: B023
        ratios[count] = took / base
        figures[f"n_p={count}"] = {"ratio": took / base, "us_per_instant": took / args.instants * 1e6,
                                   "setup_s": setup}
        print(f"{args.example} on {args.backend}: n_p = {count}: {took / base:.2f}x the plain instant "
              f"({took / args.instants * 1e6:.0f} us/instant; setup {setup:.1f} s)")
    counts = np.array(sorted(ratios))
    if len(counts) > 1:
        slope = float(np.polyfit(counts, [ratios[c] for c in counts], 1)[0])
        figures["per_parameter"] = slope
        print(f"cost per parameter: {slope:.2f} plain instants (fit over n_p = {', '.join(map(str, counts))})")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "sensitivity.json").write_text(json.dumps(figures, indent=1) + "\n")
    return figures


if __name__ == "__main__":
    main()
