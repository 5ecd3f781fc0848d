"""The incremental potential's terms: the simple sums (inertia, body force, damping,
pull), every term in one call, and the line search."""
