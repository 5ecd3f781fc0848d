"""Elastic energies of tetrahedra (neo-Hookean, fixed corotated) and their inversion
bound."""
