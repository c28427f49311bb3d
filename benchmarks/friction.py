"""Joint friction benchmark (issue #16): what friction costs in generated C,
and how fast its Newton converges.

    python -m benchmarks.friction [--instants N] [--repeats R] [--out benchmarks/results]

1. cost: microseconds per instant of the compiled C loop (`symid solve
   --backend c`'s trajectory, rows streamed to Python and dropped) on the
   bundled slider-crank with friction in every joint (three pins and the
   guide, `slider_crank_friction.toml`) against the frictionless one
   (`slider_crank.toml`), same instants; best of R runs. Target: <= 2x.
   With valgrind, also instructions per instant by callgrind
   (`benchmarks.instructions`), which the machine's load does not change.
2. iterations: the friction Newton's iterations per instant on the bundled
   example (the Python loop, the same rule as the C), its maximum. Target: <= 3.

Prints the figures and writes `friction.json`.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections import Counter
from pathlib import Path

import numpy as np

from benchmarks import instructions
from symid import api
from symid.numeric.solve import run

ROOT = Path(__file__).resolve().parent.parent


def per_instant(example: str, instants: int, repeats: int) -> float:
    """Best microseconds per instant of the C backend's whole run."""
    study = api.prepare(api.example(example), backend="c", steps=instants)
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        count = sum(1 for _ in study.evaluator.rows(study.analysis, study.q0()))  # type: ignore[attr-defined]
        best = min(best, (time.perf_counter() - start) / count)
    return float(best * 1e6)


def iterations(example: str) -> dict[int, int]:
    """Friction Newton iterations -> instants, over the example's own run."""
    study = api.prepare(api.example(example), backend="reference")
    return dict(sorted(Counter(i.friction.iterations for i in run(study.evaluator, study.analysis,
                                                                  study.q0())).items()))


def main(argv: list[str] | None = None) -> dict[str, object]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instants", type=int, default=100_001)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = parser.parse_args(argv)
    plain = per_instant("slider_crank", args.instants, args.repeats)
    friction = per_instant("slider_crank_friction", args.instants, args.repeats)
    counts = iterations("slider_crank_friction")
    ir = ({e: instructions.per_instant(e) for e in ("slider_crank", "slider_crank_friction")}
          if instructions.available() else {})
    result: dict[str, object] = {
        "instants": args.instants, "repeats": args.repeats,
        "c_us_per_instant_frictionless": plain, "c_us_per_instant_friction": friction,
        "ratio": friction / plain, "ratio_target": 2.0,
        **({"c_instructions_per_instant_frictionless": ir["slider_crank"],
            "c_instructions_per_instant_friction": ir["slider_crank_friction"],
            "instructions_ratio": ir["slider_crank_friction"] / ir["slider_crank"]} if ir else {}),
        "newton_iterations": {str(k): v for k, v in counts.items()}, "max_newton_iterations": max(counts),
        "iterations_target": 3,
        "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                    "python": platform.python_version(), "numpy": np.__version__},
    }
    print(f"C, slider-crank, {args.instants} instants: frictionless {plain:.3f} us/instant, "
          f"friction in every joint {friction:.3f} us/instant: {friction / plain:.2f}x (target <= 2x)")
    if ir:
        print(f"callgrind: frictionless {ir['slider_crank']:.0f} instructions/instant, friction in every joint "
              f"{ir['slider_crank_friction']:.0f}: {ir['slider_crank_friction'] / ir['slider_crank']:.2f}x "
              f"(target <= 2x)")
    print(f"friction Newton on slider_crank_friction: max {max(counts)} iterations (target <= 3); "
          f"instants per count {counts}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "friction.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
