"""symid: symbolic derivation and code generation for planar multibody inverse dynamics."""
