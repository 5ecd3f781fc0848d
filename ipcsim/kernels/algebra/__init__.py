"""Small dense linear algebra, the scatter of per-stencil gradients and the assembly
of Newton matrices."""
