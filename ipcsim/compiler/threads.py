"""Which threads numba's parallel kernels run on: chosen on purpose, not by what happens
to be installed.

* Layer: OpenMP (GNU libgomp, waiting passively) when it loads, otherwise numba's own
  workqueue; never TBB merely because a TBB library is installed. TBB's workers spin
  while they wait, so once another process shares the cores every kernel launch costs
  milliseconds, and its pool can hold up the exit of a finished run.
* Count: one thread for small problems, where a parallel launch costs more than it saves;
  otherwise the cores that other processes leave idle (the cores this process may use,
  less the 1-minute load average). On one thread the kernels' serial variants run and
  are the only ones compiled (``twin.py``), or none at all where they were compiled
  ahead of time (``aot.py``), and numba's thread pool is never started.

``NUMBA_THREADING_LAYER`` and ``NUMBA_NUM_THREADS`` set by the user win, and
``IPCSIM_THREADS`` fixes the count. OpenBLAS (numpy's and CHOLMOD's) is kept on one
thread by the command line (``cli.py``, before numpy loads; ``OPENBLAS_NUM_THREADS`` set
by the user wins).
"""

from __future__ import annotations

import os
import warnings

# Below this many vertices a scene runs on one thread (docs/benchmarks.md, "Threads").
PARALLEL_FROM_VERTICES = 5000

_layer_chosen = False


_mode = {"parallel": False}


def run_parallel(on: bool) -> None:
    """Call (and compile) the kernels' parallel variants from now on (``on``), or their
    serial ones (``twin.py``)."""
    _mode["parallel"] = bool(on)


def running_parallel() -> bool:
    return _mode["parallel"]


def choose_layer(numba) -> str:
    """Set numba's threading layer (once, before any parallel kernel runs): called with
    numba as soon as it is imported (``jit.numba_module``)."""
    global _layer_chosen
    if not _layer_chosen and "NUMBA_THREADING_LAYER" not in os.environ:
        try:
            from numba.np.ufunc import omppool  # noqa: F401  (needs libgomp)
            numba.config.THREADING_LAYER = "omp"
        except ImportError:
            numba.config.THREADING_LAYER = "workqueue"
        _layer_chosen = True
    return numba.config.THREADING_LAYER


def max_threads() -> int:
    """numba's thread count limit: ``NUMBA_NUM_THREADS``, or the CPUs this process may
    run on (numba's default, read without importing numba)."""
    fixed = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if fixed.isdecimal() and int(fixed) > 0:
        return int(fixed)
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def idle_cores() -> int:
    """Cores this process may run on that other processes do not keep busy."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    try:
        busy = os.getloadavg()[0]
    except OSError:
        busy = 0.0
    return max(1, min(cores or 1, round((cores or 1) - busy)))


def threads_for(n_vertices: int) -> int:
    """The thread count for a problem of n_vertices, as the module docstring says."""
    fixed = os.environ.get("IPCSIM_THREADS", "").strip()
    if fixed:
        if fixed.isdecimal() and int(fixed) > 0:
            return min(int(fixed), max_threads())
        warnings.warn(f"IPCSIM_THREADS={fixed[:20]!r} is not a positive integer; ignored",
                      stacklevel=2)
    if n_vertices < PARALLEL_FROM_VERTICES:
        return 1
    return min(idle_cores(), max_threads())
