"""Kernels as Python sees them: compiled ahead of time where they can be, by numba when not.

Every kernel is declared with this module's ``@njit(...)`` (numba's options; always
``cache=True``) or with ``@kernel(...)`` (``twin.py``). A call from Python runs

1. the kernel compiled ahead of time for exactly these argument types (``aot.py``), when
   ipcsim was installed with its compiled kernels and they were built from these sources;
2. otherwise numba's dispatcher, compiled on first use and cached beside the sources.

numba itself is imported only for 2 (``numba_module``): importing it and loading cached
kernels costs about a second and 100 MB, more than a small scene's whole run. A kernel's
numba dispatcher is made when first needed; the kernels it calls are bound into a copy of
its globals then, as numba's own dispatchers (``bind_callees``), so numba compiles what it
always compiled. ``prange`` is ``range`` until a kernel is compiled parallel.
"""

from __future__ import annotations

import functools
import types

from . import aot


def prange(*args):
    """``numba.prange`` in a kernel compiled parallel; ``range`` everywhere else."""
    return range(*args)


_numba = None
_before_loading = []  # what before_numba_loads was given, called once before numba loads


def before_numba_loads(callback) -> None:
    """Call ``callback()`` just before this process imports numba; nothing if it has."""
    if _numba is None:
        _before_loading.append(callback)


def numba_module():
    """numba, imported on first need, with the threading layer and the compile clock set."""
    global _numba
    if _numba is None:
        for callback in _before_loading:
            callback()
        _before_loading.clear()
        import numba

        from .compiling import listen
        from .threads import choose_layer

        choose_layer(numba)
        listen(numba)
        _numba = numba
    return _numba


def numba_loaded() -> bool:
    """Whether this process has imported numba (a kernel had no compiled match)."""
    return _numba is not None


def bind_callees(py_func, parallel: bool, name: str | None = None):
    """A copy of ``py_func`` whose globals name numba dispatchers where the source names
    kernels (``Compiled``: their variant of ``parallel``),
    and ``numba.prange`` where it names ``prange``. The copy keeps the code object, so
    numba's cache knows it as the source function (under ``name``, if given)."""
    names = dict(py_func.__globals__)
    for global_name in py_func.__code__.co_names:
        value = names.get(global_name)
        if isinstance(value, Compiled):
            names[global_name] = value.variant(parallel)
        elif value is prange:
            names[global_name] = numba_module().prange
    copy = types.FunctionType(py_func.__code__, names, py_func.__name__,
                              py_func.__defaults__, py_func.__closure__)
    copy.__qualname__ = name or py_func.__qualname__
    copy.__module__, copy.__doc__ = py_func.__module__, py_func.__doc__
    return copy


class Compiled:
    """A kernel as the kernels that call it see it: ``variant(parallel)`` is the numba
    dispatcher a caller compiled ``parallel`` (or not) binds to."""

    def variant(self, parallel: bool):
        raise NotImplementedError


class Jit(Compiled):
    """A kernel of one variant: calling it runs its compiled match or numba's dispatcher."""

    def __init__(self, py_func, options: dict):
        self.py_func = py_func
        self.options = options
        self._dispatcher = None
        self.compiled = aot.compiled_entry(py_func)  # argument types -> compiled function
        self.match = aot.match_on_first_call(self)  # args -> its compiled function
        functools.update_wrapper(self, py_func)

    def dispatcher(self):
        """numba's dispatcher of this kernel (made, not compiled, on first use)."""
        if self._dispatcher is None:
            numba = numba_module()
            parallel = bool(self.options.get("parallel", False))
            self._dispatcher = numba.njit(cache=True, **self.options)(
                bind_callees(self.py_func, parallel))
        return self._dispatcher

    def variant(self, parallel: bool):
        return self.dispatcher()  # one variant, whatever the caller's

    def __call__(self, *args):
        run = self.match(args)
        if run is not None:
            return run(*args)
        aot.note_jit_call(self.py_func, args)
        return self.dispatcher()(*args)

    def __getattr__(self, name):
        # numba's dispatcher answers the rest (signatures, overloads, ...)
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.dispatcher(), name)


def njit(*args, **options):
    """``@njit`` or ``@njit(inline="always", ...)``: numba's options; ``cache=True`` always."""
    options.pop("cache", None)
    if args and callable(args[0]):
        return Jit(args[0], options)

    def wrap(py_func):
        return Jit(py_func, options)
    return wrap
