"""Watch every Newton iterate of a simulation: ``watch_iterates(sim, seen)`` calls
``seen(x, evaluation)`` for each position Newton evaluates the problem at (each iterate
and the end of every solve), with the ``Evaluation`` there (energy, contacts, κ)."""

from __future__ import annotations


def watch_iterates(sim, seen) -> None:
    sim.newton.watch = seen
