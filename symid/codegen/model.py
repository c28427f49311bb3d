"""What every target renders from: the flat system, its elimination plan and
the numbers of one mechanism, for one set of options."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symid.symbolic.assemble import Layout, assemble
from symid.codegen import sparse
from symid.codegen.flat import Flat, Options, build
from symid.errors import AnalysisError
from symid.model.mechanism import Mechanism
from symid.model.mechanism import parameter_symbol
from symid.model.params import base_names, parameter_values, to_float


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

    @property
    def name(self) -> str:
        return self.flat.name


def options_for(mech: Mechanism) -> Options:
    """The generation options the mechanism's `[analysis]` asks for."""
    a = mech.analysis
    groups = a.output_groups()
    reactions: tuple[str, ...] = ()
    if "reactions" in groups and a.kind != "kinematics":
        wanted = a.reactions if a.reactions is not None else tuple(c.name for c in mech.constraints)
        reactions = tuple(c.name for c in mech.constraints if c.name in wanted)
    return Options(kind=a.kind, outputs=groups, reactions=reactions)


def code_model(mech: Mechanism, options: Options | None = None) -> CodeModel:
    """Build the flat system and fix the elimination order at q(t0)."""
    from symid.numeric.reference import ReferenceEvaluator
    from symid.numeric.evaluator import Needs
    from symid.symbolic.columns import columns
    from symid.numeric.solve import newton

    options = options or options_for(mech)
    layout = assemble(mech)
    values = parameter_values(mech.parameters)
    defaults = [values[parameter_symbol(n)] for n in base_names(mech.parameters)]
    flat = build(layout, options, defaults)
    q0 = np.array([to_float(v, values) for b in mech.bodies for v in b.q0])
    t0 = mech.analysis.t0
    reference = ReferenceEvaluator(layout, values, Needs(velocity=False))
    # a driver's derivatives may be inf or NaN at t0 (evaluated with f): the
    # solver reports that at run time, the plan needs only Phi_q
    with np.errstate(all="ignore"):
        try:
            q0, _ = newton(reference, q0, t0, mech.analysis.tol)
        except AnalysisError:
            pass  # the plan still needs a sample; the solver reports the failure at run time
        sample = reference.phi_q(q0, t0)
    plan = sparse.plan([(r, c) for r, c, _ in flat.jac], sample)
    cols = tuple(columns(layout, _analysis_like(mech, options)))
    return CodeModel(flat, plan, layout, cols, tuple(float(v) for v in q0))


def _analysis_like(mech: Mechanism, options: Options):  # type: ignore[no-untyped-def]
    import dataclasses

    return dataclasses.replace(mech.analysis, kind=options.kind, outputs=options.outputs,
                               reactions=options.reactions)

