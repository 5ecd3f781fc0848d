"""The cycle collector held back while the ``ipcsim`` process starts.

Loading numpy and ipcsim's modules makes some 40,000 container objects that live on and
a few hundred that are garbage, yet the collector's passes over them took 10–14 ms of a
tiny scene's 0.4 s run (docs/benchmarks.md, "The collector paused while the process
starts"). So ``console`` pauses it before its first import (:func:`pause_collector`). A
run resumes it before its first step, any other command before it begins its work, the
kernels just before numba loads (its compiler makes garbage cycles by the hundred
thousand), and ``console`` once ``main`` returns or raises, wherever it stopped
(:func:`resume_collector`). Code that calls ``ipcsim.cli.main`` or ``ipcsim.run``
itself is never paused.
"""

from __future__ import annotations

import gc

_paused = False  # True between pause_collector and resume_collector

# Container objects made (less those freed) during the pause above which the start loaded
# more than ipcsim (about 40,000 for a tiny scene, numpy's included): numba compiling
# kernels, a renderer. Their garbage cycles (570,000 objects for a first compile) are
# collected before the rest is frozen, which would keep them for good.
COLLECT_ABOVE = 100_000


def pause_collector() -> None:
    """Stop automatic collections, if they run, until :func:`resume_collector`."""
    global _paused
    if gc.isenabled():
        gc.disable()
        _paused = True
        from .kernels.jit import before_numba_loads  # loads numpy: after the pause begins

        # numba's compiler makes garbage cycles by the hundred thousand: not while paused
        before_numba_loads(resume_collector)


def resume_collector() -> None:
    """End the pause, if there is one. What start-up made (modules, the model) is moved
    out of the collector's reach first (``gc.freeze``): later passes need not walk it.
    A start that made more than ``COLLECT_ABOVE`` objects is collected before that."""
    global _paused
    if _paused:
        _paused = False
        if gc.get_count()[0] > COLLECT_ABOVE:
            gc.collect()
        gc.freeze()
        gc.enable()
