"""Typed errors. Library code raises these; only ``ipcsim.cli.main`` turns them into
a message and an exit status (2 for bad input, 3 for a failed simulation)."""

from __future__ import annotations

EXCERPT_CHARS = 40  # at most this much of a user's text is quoted in a message


def excerpt(text, limit: int = EXCERPT_CHARS) -> str:
    """``text`` as a message may quote it: at most ``limit`` characters, control and other
    unprintable characters escaped (``\\x00``), and a note of how much was left out."""
    s = str(text)
    head = s[:limit]
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in head)
    if len(s) > limit:
        shown += f"... ({len(s)} characters)"
    return shown


def one_line(message: str, limit: int = 500) -> str:
    """A message as one line of at most about ``limit`` characters, control characters
    (a file name's escape sequence, say) escaped as ``excerpt`` does."""
    flat = " ".join(str(message).split())
    flat = "".join(c if c.isprintable() else repr(c)[1:-1] for c in flat)
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."



class IpcsimError(Exception):
    """Base class of every error ipcsim reports to a user."""

    exit_status = 2


class ArgumentError(IpcsimError, ValueError):
    """An argument of a command or of the Python API that cannot be used (``--steps -1``,
    ``ipcsim.run(spec, steps=1.5)``); ``ipcsim.arguments`` checks both alike."""


class SceneError(IpcsimError):
    """A mistake in a scene file, reported as ``path:line: message``."""

    def __init__(self, path, line: int | None, message: str):
        self.path = str(path) if path is not None else None
        self.line = line
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        where = self.path or "<scene>"
        if self.line is not None:
            where = f"{where}:{self.line}"
        return f"{where}: {self.message}"


class MeshError(SceneError):
    """A mesh file that cannot be used (missing, unreadable, degenerate).

    ``line`` is the line of the scene that names the mesh; once the model builder knows
    the scene file it sets ``scene``, and the message reads ``scene:line: mesh: problem``.
    """

    scene: str | None = None

    def __str__(self) -> str:
        if self.scene is not None:
            where = f"{self.scene}:{self.line}" if self.line is not None else self.scene
            return f"{where}: {self.path}: {self.message}"
        if self.line is not None:
            return f"{self.path}: {self.message} (scene line {self.line})"
        return f"{self.path}: {self.message}"


class SolverError(IpcsimError):
    """The simulation itself failed (NaN, infinite energy, no feasible step). ``label``
    names the kind of failure where a benchmark tells them apart (the SQP / QP baselines:
    "Blow-up", "QP failure"); None otherwise. With adaptive steps ``attempts`` and
    ``newton`` hold the failed step's steps.csv and newton.csv rows, so that the logs
    show how its steps shrank."""

    exit_status = 3
    label: str | None = None
    attempts: tuple[dict, ...] = ()
    newton: tuple[dict, ...] = ()

    def __init__(self, message: str = "", label: str | None = None):
        super().__init__(message)
        if label is not None:
            self.label = label


class NonFiniteError(SolverError):
    """NaN or infinity appeared during a step; names the quantity and the terms that hold
    it. The simulation adds the step number (``step`` is None until it does)."""

    def __init__(self, quantity: str, terms: list[str], iteration: int, step: int | None = None):
        self.quantity, self.terms, self.iteration, self.step = quantity, terms, iteration, step
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"Newton iteration {self.iteration}"
        if self.step is not None:
            where = f"step {self.step}, {where}"
        if self.terms:
            culprit = "in the " + " and ".join(self.terms) + " term" + ("s" if len(self.terms) > 1 else "")
        else:
            culprit = "although every term is finite (the linear solve failed)"
        return f"{where}: the {self.quantity} is not finite (NaN or infinity) {culprit}"


class RunFailed(SolverError):
    """A run's simulation failed (NaN, solver); its frames, logs and run.json up to the
    last completed step are written. ``__cause__`` is the solver's own error."""

    def __init__(self, message: str, exit_status: int = 3):
        super().__init__(message)
        self.exit_status = exit_status


class RunInterrupted(IpcsimError):
    """A run stopped on Ctrl-C after a completed step; its folder can be resumed."""

    exit_status = 130


class OutputError(IpcsimError):
    """Output cannot be written (a full disk, a read-only folder); what was written before
    stays complete, and a run can be resumed once the cause is removed."""


class InfeasibleStartError(IpcsimError):
    """The initial state breaks what IPC guarantees (intersecting surfaces, a vertex below
    a plane, an inverted tet), so no step could keep it."""

    exit_status = 2
