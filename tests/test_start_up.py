"""ipcsim/start_up.py: the cycle collector paused while the ``ipcsim`` process starts,
and the process ended without the interpreter's teardown."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import weakref

import pytest

from ipcsim import start_up


class _Node:
    pass


def test_a_small_start_is_frozen_without_a_collection(monkeypatch):
    calls = []
    monkeypatch.setattr(gc, "collect", lambda *args: calls.append("collect") or 0)
    monkeypatch.setattr(gc, "freeze", lambda: calls.append("freeze"))
    try:
        start_up.pause_collector()
        assert not gc.isenabled()
        start_up.resume_collector()
        assert gc.isenabled() and calls == ["freeze"]
        start_up.resume_collector()  # a second resume does nothing
        assert calls == ["freeze"]
    finally:
        gc.enable()


def test_a_large_start_is_collected_before_it_is_frozen():
    """Garbage cycles made during a start that loaded more than ipcsim (numba compiling)
    are freed, not frozen for the rest of the run; a small start's are frozen."""
    for extra, freed in ((2 * start_up.COLLECT_ABOVE, True), (0, False)):
        try:
            start_up.pause_collector()
            cycle = _Node()
            cycle.itself = cycle
            gone = weakref.ref(cycle)
            del cycle
            kept = [[] for _ in range(extra)]
            start_up.resume_collector()
            gc.collect()  # a frozen object outlives even a full collection
            assert (gone() is None) == freed and gc.isenabled()
            del kept
        finally:
            gc.enable()
            gc.unfreeze()  # give the test session's objects back to the collector


def test_nothing_is_resumed_that_was_not_paused(monkeypatch):
    """Code that turned the collector off itself keeps it off."""
    calls = []
    monkeypatch.setattr(gc, "freeze", lambda: calls.append("freeze"))
    gc.disable()
    try:
        start_up.pause_collector()
        start_up.resume_collector()
        assert not gc.isenabled() and calls == []
    finally:
        gc.enable()


def test_loading_numba_ends_the_pause(monkeypatch):
    """numba's compiler makes garbage cycles by the hundred thousand: the pause ends before
    numba loads (a kernel without a compiled match, a first parallel run)."""
    from ipcsim.compiler import compiling, jit, threads

    monkeypatch.setattr(jit, "_numba", None)  # as in a process that has not loaded it
    monkeypatch.setattr(jit, "_before_loading", [])
    monkeypatch.setattr(compiling, "listen", lambda numba: None)  # set up once already
    monkeypatch.setattr(threads, "choose_layer", lambda numba: None)
    monkeypatch.setattr(gc, "freeze", lambda: None)  # leave the test session collectable
    try:
        start_up.pause_collector()
        assert not gc.isenabled()
        assert jit.numba_module().__name__ == "numba" and gc.isenabled()
    finally:
        gc.enable()


@pytest.mark.parametrize("waiting", ["nothing", "an exit handler", "a thread"])
def test_the_process_ends_with_its_status_and_its_output_whatever_waits(waiting):
    """``end_process`` flushes what was printed (block-buffered into a pipe) and exits
    with the status; an exit handler or a thread still running is waited for, as the
    interpreter's own exit does."""
    code = ("import atexit, sys, threading, time\n"
            "from ipcsim.start_up import end_process\n"
            "print('printed', end='')\n"
            "sys.stderr.write('said')\n"
            f"waiting = {waiting!r}\n"
            "if waiting == 'an exit handler':\n"
            "    atexit.register(lambda: print(' handled', end=''))\n"
            "if waiting == 'a thread':\n"
            "    threading.Thread(target=lambda: (time.sleep(0.2), print(' joined', end=''))"
            ").start()\n"
            "end_process(3)\n"
            "print(' after')\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=60)
    assert done.returncode == 3
    assert done.stderr == "said"
    assert done.stdout == {"nothing": "printed", "an exit handler": "printed handled",
                           "a thread": "printed joined"}[waiting]
