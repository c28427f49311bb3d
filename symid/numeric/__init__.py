"""The solve loop over time and its numerical stability tools.

Holds the evaluator protocol every backend implements (`evaluator`), the
reference evaluator (each family lambdified), Newton with its convergence
rule, the kinematic and inverse-dynamic instant, the non-finite and jump
guarantees, and conditioning, redundancy and branch checks. May import
`symid.io`, `symid.symbolic`, `symid.model` and the base modules; it knows
backends only through the protocol.
"""
