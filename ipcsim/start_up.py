"""The ``ipcsim`` process's start and end: the cycle collector held back while it
starts, and an exit without the interpreter's teardown.

Loading numpy and ipcsim's modules makes some 40,000 container objects that live on and
a few hundred that are garbage, yet the collector's passes over them took 10–14 ms of a
tiny scene's 0.4 s run (measured when this was written; the repository's history has
the figures). So ``console`` pauses it before its first import (:func:`pause_collector`). A
run resumes it before its first step, any other command before it begins its work, the
kernels just before numba loads (its compiler makes garbage cycles by the hundred
thousand), and ``console`` once ``main`` returns or raises, wherever it stopped
(:func:`resume_collector`). Code that calls ``ipcsim.cli.main`` or ``ipcsim.run``
itself is never paused.

When ``main`` has returned, every file the command wrote is closed: what the interpreter
does after that (freeing each object, tearing down each module) changes nothing on disk
yet took about 7 ms of a tiny scene's 0.28 s run. :func:`end_process` leaves it out where
nothing else is waiting for the exit.
"""

from __future__ import annotations

import atexit
import gc
import os
import sys
import threading
from typing import NoReturn

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
        from .compiler.jit import before_numba_loads  # loads numpy: after the pause begins

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


def end_process(status: int) -> NoReturn:
    """Exit with ``status`` once the command is done: the standard streams are flushed,
    then the process ends at once (``os._exit``). Where an exit handler is registered
    (a renderer's, a thread pool's) or a thread that is not a daemon still runs, the
    interpreter's own exit runs them instead (``sys.exit``)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing more to say
            pass
    if isinstance(status, int) and _exit_waits_for_nothing():
        os._exit(status)
    sys.exit(status)


def _exit_waits_for_nothing() -> bool:
    """No exit handler is registered and no thread but this one needs to finish (an
    interpreter without ``atexit._ncallbacks`` is taken to have handlers)."""
    handlers = getattr(atexit, "_ncallbacks", None)
    if handlers is None or handlers() > 0:
        return False
    current = threading.current_thread()
    return all(t is current or t.daemon for t in threading.enumerate())
