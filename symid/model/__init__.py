"""The mechanism as plain data.

Holds what a mechanism is (bodies, elements, the analysis asked for), what a
constraint or force family declares (its keys), the expression grammar,
parameters and motion laws. Nothing here derives or evaluates. May import
only the base modules (`symid.errors`, `symid.text`, `symid.progress`);
every other layer may import it.
"""
