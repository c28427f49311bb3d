"""What sympy derives: generic symbols, the constraint and force families,
their derivation (`Phi_q`, `nu`, `gamma`, reactions) once per family, the
assembly of a mechanism into rows and columns, and the columns' names.

May import `symid.model` and the base modules; never a numeric, code or
output layer.
"""
