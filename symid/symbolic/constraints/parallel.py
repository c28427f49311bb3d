"""Planar parallel-1: a_i = A_i v_i stays parallel to a_j = A_j v_j."""

from __future__ import annotations

from symid.symbolic import symbols as s
from symid.model.elements import ConstraintType, body, vector

parallel = ConstraintType(
    name="parallel",
    keys=(body("i"), body("j"), vector("vi"), vector("vj")),
    points={"i": None, "j": None},
    phi=lambda o: [((s.A("i") * s.vector("vi")).T * s.R.T * (s.A("j") * s.vector("vj")))[0]],
)

TYPES = (parallel,)
