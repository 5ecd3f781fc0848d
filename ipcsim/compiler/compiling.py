"""How long this process has spent compiling kernels, and a word to the user when it starts.

numba compiles a kernel on its first call unless its cache (beside the sources) holds it
for this machine; only a first run after installing (or after the kernels changed) pays.
Kernels compiled ahead of time (``aot.py``) never compile. The clock listens to numba's
``numba:compile`` events, which fire on cache misses only, once numba is imported
(``jit.numba_module`` calls ``listen``), so a run can leave compile time out of its
time-left estimate and say once why a first step is slow.
"""

from __future__ import annotations

import time


class _CompileClock:
    def __init__(self):
        self.depth = 0
        self.seconds = 0.0
        self._start = 0.0
        self.on_first = None  # called once, when the first compile starts

    def on_start(self, event):
        if self.depth == 0:
            self._start = time.perf_counter()
            if self.on_first is not None:
                callback, self.on_first = self.on_first, None
                callback()
        self.depth += 1

    def on_end(self, event):
        self.depth -= 1
        if self.depth == 0:
            self.seconds += time.perf_counter() - self._start


_clock = _CompileClock()


def listen(numba) -> None:
    """Start the clock on numba's compile events (numba just imported)."""
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, e):
            _clock.on_start(e)

        def on_end(self, e):
            _clock.on_end(e)

    event.register("numba:compile", Listener())


def compile_seconds() -> float:
    """Wall seconds spent compiling kernels in this process so far."""
    return _clock.seconds


def when_compiling_starts(callback) -> None:
    """Call ``callback()`` once, when this process first has to compile a kernel."""
    _clock.on_first = callback
