"""Watch every Newton iterate of a simulation: ``watch_iterates(sim, seen)`` calls
``seen(x, evaluation)`` for each position the objective is evaluated at (each iterate and
the end of every solve), with the ``Evaluation`` there (energy, contacts, κ)."""

from __future__ import annotations


def watch_iterates(sim, seen) -> None:
    solve = sim.newton.solve

    def watched(objective, x0, tol):
        evaluate = objective.evaluate

        def evaluate_and_report(x, order=2, **options):
            ev = evaluate(x, order, **options)
            seen(x, ev)
            return ev

        objective.evaluate = evaluate_and_report
        return solve(objective, x0, tol)

    sim.newton.solve = watched
