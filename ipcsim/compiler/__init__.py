"""Kernels: numba's, compiled ahead of time when ipcsim is installed (``aot.py``) and by
numba where not (``jit.py``); the only package that imports numba, and only when a kernel
must be compiled.

OpenMP worker threads that spin while waiting for work make every parallel kernel call
cost milliseconds once the other core is busy (measured 15x slower steps on 2 cores);
passive waiting costs microseconds. The setting must be made before numba starts its
threads, so it is made here, unless the user chose otherwise; numba's threading layer is
chosen when numba is imported (``threads.py``), before any parallel kernel can run.
"""

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
