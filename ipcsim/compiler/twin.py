"""Kernels compiled in two variants from one source: serial, and parallel.

A parallel numba kernel (``prange`` loops run on numba's threads) costs tens to hundreds
of microseconds per launch, more than a small problem's whole loop, and compiling it costs
several times what the serial kernel does (numba's parfor passes). So each kernel that has
a ``prange`` loop, or calls one that has, is declared with ``@kernel(...)`` and compiled on
first use in the variant the process runs: serial while it runs on one thread (every small
scene, and the test suite), parallel once ``use_threads`` chose more than one. A
variant calls the same variant of every kernel it calls. The two variants share the source
and differ in name only in numba's cache (``<name>_serial``, ``<name>_parallel``).
"""

from __future__ import annotations

import functools

from . import aot
from .jit import Compiled, bind_callees, numba_module
from .threads import run_parallel, running_parallel, threads_for


def use_threads(n_vertices: int) -> int:
    """Run on the thread count chosen for a problem of n_vertices (``threads.py``): the
    parallel variants on more than one, with numba and its threading layer loaded now."""
    n = threads_for(n_vertices)
    run_parallel(n > 1)
    if n > 1:
        numba = numba_module()
        if n != numba.get_num_threads():
            numba.set_num_threads(n)
    return n


class Kernel(Compiled):
    """A kernel of both variants; calling it runs the variant of the current mode: the
    serial one compiled ahead of time where it matches the arguments (``jit.py``)."""

    def __init__(self, py_func, parallel: bool, options: dict):
        self.py_func = py_func
        self.parallel = parallel  # the source has prange loops to run in parallel
        self.options = options
        self._variants = {}
        self.compiled = aot.compiled_entry(py_func)  # serial variant's, by argument types
        self.match = aot.match_on_first_call(self)  # args -> its compiled function
        functools.update_wrapper(self, py_func)

    def variant(self, parallel: bool):
        """The njit dispatcher of one variant, made on first use (when its module and
        every module it names are loaded): the kernels it calls are bound to their
        variant of the same mode."""
        dispatcher = self._variants.get(parallel)
        if dispatcher is None:
            f = self.py_func
            name = f"{f.__qualname__}_{'parallel' if parallel else 'serial'}"
            dispatcher = numba_module().njit(cache=True, parallel=parallel and self.parallel,
                                             **self.options)(bind_callees(f, parallel, name))
            self._variants[parallel] = dispatcher
        return dispatcher

    def __call__(self, *args):
        parallel = running_parallel()
        if not parallel:
            run = self.match(args)
            if run is not None:
                return run(*args)
        aot.note_jit_call(self.py_func, args)
        return self.variant(parallel)(*args)

    @property
    def signatures(self) -> list:
        """Every signature numba compiled, over both variants."""
        return [sig for d in self._variants.values() for sig in d.signatures]


def kernel(parallel: bool = False, **options):
    """Declare a kernel of two variants: ``@kernel(parallel=True, error_model="numpy")``
    for one with ``prange`` loops, ``@kernel()`` for one that only calls such kernels.
    ``options`` go to ``numba.njit`` (always with ``cache=True``)."""
    def wrap(py_func):
        return Kernel(py_func, parallel, options)
    return wrap
