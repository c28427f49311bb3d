"""Code generation: per-mechanism solvers with nothing left to interpret.

`flat.build` substitutes every instance into its family's derivation (linear
in the mechanism's size), `sparse.plan` fixes the elimination order of
`Phi_q`, and each target in the `symid.codegen.targets` registry (the C
target: the package `symid.codegen.c`) renders templates from
`templates/<target>/`.
"""
