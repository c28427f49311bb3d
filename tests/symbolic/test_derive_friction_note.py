"""Found trying symid as a new user: `symid derive FILE` of a mechanism with
joint friction showed Q^A without it and said nothing; a note now names the
joints whose friction is solved with the reactions instead."""

from __future__ import annotations

from symid import api
from symid.tools.show import derive_mechanism


def test_derive_of_a_mechanism_with_friction_notes_its_joints() -> None:
    derivation = derive_mechanism(str(api.example("slider_crank_friction")))
    notes = [n for n in derivation.notes if "friction" in n]
    assert len(notes) == 1 and "not in Q^A" in notes[0]
    assert "friction" in derivation.latex()


def test_derive_without_friction_has_no_friction_note() -> None:
    assert not any("friction" in n for n in derive_mechanism(str(api.example("slider_crank"))).notes)
