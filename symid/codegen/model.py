"""What every target renders from: the flat system, its elimination plan and
the numbers of one mechanism, for one set of options."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from symid.symbolic.assemble import Layout, assemble
from symid.codegen import sparse
from symid.codegen.flat import Flat, Options, build
from symid.codegen.forked import Pending
from symid.errors import AnalysisError
from symid.model.mechanism import Mechanism
from symid.model.mechanism import parameter_symbol
from symid.model.params import base_names


@dataclass(frozen=True)
class CodeModel:
    """A mechanism ready to render.

    Attributes:
        row_columns: the contract's column names of one trajectory row.
        q0: the assembled configuration at t0 (the plan's sample), size ng.
    """

    flat: Flat
    plan: sparse.Plan
    layout: Layout
    row_columns: tuple[str, ...]
    q0: tuple[float, ...]
    loop_parts: Any = None  # the C target's looped parts, when `looped` found them (c_loops.parts)

    @property
    def name(self) -> str:
        return self.flat.name


def options_for(mech: Mechanism) -> Options:
    """The generation options the mechanism's `[analysis]` asks for."""
    a = mech.analysis
    wanted = mech.solved_reactions
    reactions = tuple(c.name for c in mech.constraints if c.name in wanted)  # in file order
    return Options(kind=a.kind, outputs=a.output_groups(), reactions=reactions)


# Past this many coordinates setup assembles with a sparse LU and samples
# Phi_q entry by entry (nothing ng x ng); below, the dense path of the run's
# own Newton, whose configuration (to the last bit) the committed generated
# code of the examples was planned at.
DENSE_SETUP = 150


def _assemble_sparse(reference, q0: np.ndarray, t0: float, tol: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    from symid.numeric.assembly import assemble

    try:
        return assemble(reference, q0, t0, tol)
    except AnalysisError:
        return q0  # the plan still needs a sample; the solver reports the failure at run time


def code_model(mech: Mechanism, options: Options | None = None, looped: bool = False,
               meanwhile: Callable[[Pending[Any]], None] | None = None) -> CodeModel:
    """Build the flat system and fix the elimination order at q(t0).

    looped: for the C target, whose looped kernels compute the rows and
    reactions of the members they loop over: those are not substituted
    (`flat.build`'s `looped`; the flat system is then for that target only).
    meanwhile: work of the caller's (e.g. loading its templates) to do while
    the plan's sample is computed in a child process (`symid.codegen.forked`),
    given the pending sample to poll (`ready`); not called without a child.
    """
    from symid.symbolic.columns import columns

    options = options or options_for(mech)
    layout = assemble(mech)
    values = layout.values
    defaults = [values[parameter_symbol(n)] for n in base_names(mech.parameters)]
    q0 = np.array(layout.q0)
    parts = _loop_parts(layout) if looped else None
    index = {id(g): k for k, g in enumerate(layout.constraint_groups)}
    flat = build(layout, options, defaults,
                 frozenset((index[id(p.group)], m) for p in parts or [] for m in p.members))
    # the sample (lambdify, scipy's import, Newton) runs beside the caller's
    # `meanwhile`, forked after the derivation, which it shares; with nothing
    # to do meanwhile, here (a child would only add the fork's cost)
    sample = Pending(lambda: _sample(layout, values, q0, mech.analysis.t0, mech.analysis.tol),
                     fork=meanwhile is not None)
    if meanwhile is not None and not sample.ready():
        meanwhile(sample)
    q0, phi_q = sample.result()
    pattern = [(r, c) for r, c, _ in flat.jac]
    if isinstance(phi_q, dict):  # entry by entry (sparse setup)
        plan = sparse.plan(pattern, [phi_q.get(rc, 0.0) for rc in pattern], layout.ng)
    else:
        plan = sparse.plan(pattern, phi_q)
    cols = tuple(columns(layout, _analysis_like(mech, options)))
    if options.sensitivity:  # after all other columns, columns outer and parameters inner
        cols += tuple(f"d({c})/d({n})" for c in options.sensitivity_of for n in options.sensitivity)
    return CodeModel(flat, plan, layout, cols, settled(q0), parts)


# What is written of q0 (the C header's default_q0) is q0 rounded to 13
# decimal places below the leading digit of its scale: the mechanism's length
# scale (the largest |x|, |y|) for positions, 1 rad for angles. Newton leaves
# rounding noise of a few eps of the scale in the last bits, which differs with
# libm and BLAS (-1.6e-33 here, 2.3e-33 on another machine, for a coordinate
# that is 0; 0.25000000000000006 for 0.25): 1e-13 of the scale is far above
# that noise and far below the assembly's tolerance, so the written numbers are
# the same on every machine (unless one lies within the noise of a rounding
# boundary) and the file's round numbers stay round.
DECIMALS = 13


def settled(q0: np.ndarray) -> tuple[float, ...]:
    """q0 as written: each value rounded to 10^-DECIMALS of its scale's leading
    digit (a correctly rounded decimal: noise about 0 is 0, never -0.0)."""
    q = [float(v) for v in q0]
    lengths = [abs(v) for k, v in enumerate(q) if k % 3 != 2 and math.isfinite(v)]
    length = max(lengths, default=0.0)

    def places(scale: float) -> int:
        return DECIMALS - math.floor(math.log10(scale)) if scale > 0 else DECIMALS

    return tuple(round(v, places(1.0 if k % 3 == 2 else length)) + 0.0 if math.isfinite(v) else v
                 for k, v in enumerate(q))


def _sample(layout: Layout, values: dict[Any, float], q0: np.ndarray, t0: float,
            tol: float) -> tuple[np.ndarray, np.ndarray | dict[tuple[int, int], float]]:
    """The assembled configuration at t0 and Phi_q there (dense, or entry by
    entry past DENSE_SETUP coordinates): what the elimination plan is fixed at."""
    from symid.numeric.evaluator import Needs
    from symid.numeric.reference import ReferenceEvaluator
    from symid.numeric.solve import newton

    reference = ReferenceEvaluator(layout, values, Needs(velocity=False))
    # a driver's derivatives may be inf or NaN at t0 (evaluated with f): the
    # solver reports that at run time, the plan needs only Phi_q
    with np.errstate(all="ignore"):
        if layout.ng > DENSE_SETUP and layout.nc == layout.ng:
            q0 = _assemble_sparse(reference, q0, t0, tol)
            rows, cols_, vals = reference.phi_q_entries(q0, t0)
            return q0, dict(zip(zip(rows.tolist(), cols_.tolist()), vals.tolist()))
        try:
            q0, _ = newton(reference, q0, t0, tol)
        except AnalysisError:
            pass  # the plan still needs a sample; the solver reports the failure at run time
        return q0, reference.phi_q(q0, t0)


def _loop_parts(layout: Layout) -> list[Any] | None:
    """The parts of the constraint groups the C target's kernels loop over."""
    from symid.codegen.c import loops as c_loops

    if layout.ng < c_loops.LOOP_MIN:
        return None
    return c_loops.parts(layout)


def _analysis_like(mech: Mechanism, options: Options):  # type: ignore[no-untyped-def]
    import dataclasses

    return dataclasses.replace(mech.analysis, kind=options.kind, outputs=options.outputs,
                               reactions=options.reactions)

