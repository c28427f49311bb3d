"""The one Newton rule: how every solve loop decides that positions have converged.

Three loops solve Phi(q, t) = 0 for q at an instant: the Python loop
(`symid.numeric.solve.newton`), the generated NumPy module (`_instant`) and
the generated C (`_newton`). Each is written from `RULE`: the templates
render its numbers, the Python loop reads them, so the rule cannot differ
between backends (tests/numeric/test_newton_rule.py renders both templates from a
changed rule and runs all four backends where only the floor lets them
converge).

The rule:
- Converged when max |Phi| <= lim and the last correction max |dq| <= lim,
  lim = max(tol, floor); or when |Phi| was within lim where the last
  correction was computed and that correction is too.
- The floor: neither can be resolved finer than rounding of the largest
  coordinate, `floor_ulps` units of 2^-52 of max(1, max |q|) (angles grow
  without bound over long runs). The Python loop measures in the scaled
  units of its `Scaling`, and floors the correction at the floor times the
  condition estimate of Phi_q (the step that rounding alone causes).
- At most `max_iterations` corrections; then "Newton did not converge".
- The Python loop damps: it halves a step until the scaled merit decreases
  by the Armijo fraction `armijo`, down to `min_damping` (below it: diverging);
  within `noise` times lim rounding may raise the residual of an exact step,
  so full steps are taken there. The generated loops take full steps and
  hand an instant that fails to the Python loop, which decides.
- The compiled C may reuse the previous instant's factors for the first
  correction (a chord step from its predictor); later corrections factor at
  the iterate, and the factors it keeps are those of the solution.
"""

from __future__ import annotations

from dataclasses import dataclass

EPS = 2.0 ** -52  # the double epsilon, numpy.finfo(float).eps


@dataclass(frozen=True)
class NewtonRule:
    """The numbers of the rule (see the module docstring)."""

    max_iterations: int = 50
    floor_ulps: float = 8.0
    armijo: float = 1e-4
    min_damping: float = 1.0 / 1024
    noise: float = 1e3

    def floor(self, size: float) -> float:
        """The rounding floor of the tolerance for coordinates of largest magnitude `size`."""
        return self.floor_ulps * EPS * max(1.0, size)


RULE = NewtonRule()
