"""The numba kernels: the arithmetic of every hot path, over arrays, by concept:
``algebra/`` (small linear algebra, scatter and assembly), ``contact/`` (distances,
barriers, broad phase, CCD, friction, exact intersection predicates), ``elasticity/``,
``terms/`` (the incremental potential's terms together, and the line search).
Declared with ``ipcsim.compiler``'s ``njit`` / ``kernel``; nothing here imports numba."""
