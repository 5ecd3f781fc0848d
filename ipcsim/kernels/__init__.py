"""Numba kernels: the only package that imports numba.

OpenMP worker threads that spin while waiting for work make every parallel kernel call
cost milliseconds once the other core is busy (measured 15x slower steps on 2 cores);
passive waiting costs microseconds. The setting must be made before numba starts its
threads, so it is made here, unless the user chose otherwise; so is the choice of the
threading layer (``threads.py``), before any parallel kernel can run.
"""

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .threads import choose_layer  # noqa: E402  (after the OpenMP setting)

choose_layer()
