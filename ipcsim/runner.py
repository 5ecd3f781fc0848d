"""A run: simulate a scene and write frames, logs, a checkpoint and the resolved scene.

``run(spec, out_dir)`` is what ``ipcsim run`` does (the command calls it) and what
``ipcsim.run`` offers to Python. Everything is built and checked before the first byte
is written: the model, the simulation's start, the output folder and, for a resume,
the checkpoint against the folder; so a bad input leaves every folder as it was, and
``mode="overwrite"`` removes the old run only once the new one can start.

Nothing is lost on a crash: each step's CSV rows are flushed before the next step starts,
frames and the checkpoint are replaced atomically, and a checkpoint (with a frame, at most
every ``CHECKPOINT_SECONDS``, and at the end) first forces everything before it to disk.
``mode="resume"`` continues from the checkpoint (after a kill, even SIGKILL, or
a full disk); Ctrl-C stops after the current step with a fresh checkpoint
(:class:`~ipcsim.errors.RunInterrupted`).
"""

from __future__ import annotations

import shlex
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from msgspec import Struct
import numpy as np

from .errors import (OutputError, RunFailed, RunInterrupted, SceneError, SolverError,
                     excerpt)
from .start_up import resume_collector

__all__ = ["run", "RunResult", "Reporter", "build", "frame_interval_for"]

MODES = ("new", "overwrite", "resume")
MAX_STEP_WARNINGS = 10  # non-converged steps named by warn(); run.json counts all
# A checkpoint, which forces everything written before it to disk, at most this often
# (wall seconds; and always at the last step and on Ctrl-C). Between checkpoints frames
# and rows are replaced atomically but not forced to disk: a killed run resumes from the
# last checkpoint and computes at most this much again.
CHECKPOINT_SECONDS = 2.0
# frames/series.pvd is rewritten whole with a frame at most this often (wall seconds), and
# brought up to date at each checkpoint and however the run ends
SERIES_SECONDS = 1.0


def _nothing(*_) -> None:
    pass


def _to_stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


class Reporter(Struct, frozen=True):
    """Where a run's messages go. The defaults (the Python API's) say nothing but
    warnings, which go to stderr; ``ipcsim run`` prints everything.

    ``say``: what the run does (its folder, modelled terms, linear solver, the summary);
    ``warn``: scene and builder warnings and steps that did not converge; ``progress``:
    "bar", "lines" or "off"; ``on_iteration``: called with every newton.csv row as it
    completes; ``scene_name``: the scene as messages name it (default: its path);
    ``command``: the command line recorded in run.json (default: none)."""

    say: Callable[[str], None] = _nothing
    warn: Callable[[str], None] = _to_stderr
    progress: str = "off"
    on_iteration: Callable[[dict], None] | None = None
    scene_name: str | None = None
    command: tuple[str, ...] | None = None


class RunResult(Struct, frozen=True, eq=False):
    """What a run did. ``steps_done`` is the run's last step (over all its invocations);
    ``first_step`` where this call began (0, or the checkpoint's step when resumed);
    ``newton_iterations`` and ``wall_s`` (s) are this call's; ``state`` the final
    ``State``."""

    out: Path
    steps_done: int
    steps_planned: int
    first_step: int
    newton_iterations: int
    steps_not_converged: int
    wall_s: float
    state: object


def frame_interval_for(scene) -> int:
    """About one frame per 0.01 s of simulated time, as the original (``playBackSpeed``
    below 1 writes denser frames)."""
    from .io.vtk import frame_interval

    frame_dt = 0.01
    if scene.playback_speed < 1.0:
        frame_dt = max(scene.dt, min(0.01, scene.playback_speed * 0.03))
    return frame_interval(scene.dt, frame_dt)


class StopRequest:
    """The first Ctrl-C (SIGINT) or SIGTERM (a batch scheduler's, ``timeout``'s) asks the
    run to stop after the current step; a second one stops at once (KeyboardInterrupt:
    the folder is still resumable from the last frame)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.requested = False
        self.at_once = False  # the second signal came
        self._previous = {}

    def _handle(self, signum, frame):
        if self.requested:
            self.at_once = True
            raise KeyboardInterrupt
        self.requested = True
        again = "Ctrl-C" if signum == signal.SIGINT else "the signal"
        print(f"\nipcsim: stopping after this step ({again} again to stop at once)",
              file=sys.stderr, flush=True)

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc):
        for s, previous in self._previous.items():
            signal.signal(s, previous)
        self._previous = {}


def build(spec, warn=_to_stderr):
    """(model, simulation) of a scene; ``warn(message)`` receives the scene's and the
    builder's warnings. A named linear solver that is not installed here (PARDISO
    without MKL) is a SceneError at the scene's ``linearSolver`` line."""
    from .model.build import build_model
    from .simulation import Simulation

    for w in spec.warnings:
        warn(w)
    model = build_model(spec)
    for w in getattr(model, "warnings", ()):
        warn(w)
    try:
        return model, Simulation(model)
    except ImportError as exc:
        if spec.linear_solver is None:
            raise  # "auto" falls back to scipy: an ImportError here is a broken install
        raise SceneError(spec.source, spec.line_of("solver.linear_solver"),
                         f"linear solver '{spec.linear_solver}' is not available here "
                         f"({excerpt(exc, 120)}); use linearSolver auto") from None


class _Run(Struct):
    """One call of :func:`run`: what was built and checked before writing."""

    scene: object
    model: object
    sim: object
    out: Path
    digest: str
    mode: str
    steps: int | None
    reporter: Reporter
    lock: object = None  # this process's hold on ``out`` (io.output_folder.FolderLock)
    render: bool = False
    first_step: int = 0  # the checkpoint's step when resuming
    frames: object = None
    step_log: object = None  # steps.csv, once opened (its totals go to run.json)
    renderer: object = None
    warned: int = 0  # steps that did not converge, in this call
    newton_total: int = 0  # Newton iterations, in this call
    checkpointed: float = 0.0  # wall clock of the last checkpoint

    @property
    def resume(self) -> bool:
        return self.mode == "resume"

    @property
    def n_steps(self) -> int:
        """The last step of this call (``steps``, at most the scene's)."""
        return self.scene.n_steps if self.steps is None else min(self.steps,
                                                                   self.scene.n_steps)

    @property
    def every(self) -> int:
        return frame_interval_for(self.scene)

    @property
    def scene_name(self) -> str:
        return self.reporter.scene_name or str(self.scene.source or "<scene>")


def _build(spec, out_dir, mode: str, steps, reporter: Reporter) -> _Run:
    """Build and check everything, and hold the output folder (created, and its lock file
    in it, where it did not exist); nothing else is written yet."""
    from .io.output_folder import default_output_folder, hold_folder, resolve_output_folder
    from .scene.digest import inputs_digest

    model, sim = build(spec, reporter.warn)
    scene_path = spec.source if spec.source is not None else Path("scene")
    requested = out_dir if out_dir is not None else default_output_folder(
        reporter.scene_name or scene_path, spec.append_str)
    out = resolve_output_folder(requested, scene_path, mode=mode)
    run = _Run(spec, model, sim, out, inputs_digest(spec), mode, steps, reporter)
    run.lock = hold_folder(out)  # before the checkpoint is read: nobody else writes now
    if run.resume:
        try:
            run.first_step = _check_resume(run)
        except BaseException:
            run.lock.release()
            raise
    return run


def _check_resume(run: _Run) -> int:
    """Validate the folder's checkpoint against the scene, the frames and the logs, then
    restore it into the simulation; returns its step. Nothing on disk changes."""
    from .io.checkpoint import CheckpointError, read_checkpoint
    from .io.resume import check_resume

    checkpoint = read_checkpoint(run.out)
    check_resume(run.out, checkpoint, inputs_sha256=run.digest,
                 n_vertices=len(run.model.mass), scene_steps=run.scene.n_steps,
                 frame_every=run.every, scene=run.scene_name,
                 adaptive=run.sim.control is not None)
    k = checkpoint["step"]
    if run.steps is not None and run.steps < k:
        raise CheckpointError(f"--steps {run.steps} lies before the checkpoint's step "
                              f"{k} in {run.out}")
    try:
        run.sim.restore(checkpoint)
    except ValueError as exc:
        raise CheckpointError(f"{run.out}: {exc}") from None
    return k


def _write_frame(run: _Run, k: int) -> None:
    st = run.sim.state
    model = run.model
    fields = None if st.plane_origins is None else {"plane_origins": st.plane_origins}
    extra = {}
    if len(model.springs):  # a mass-spring body's triangles may invert (check --frames)
        extra["mass_spring"] = np.isin(model.vertex_shape,
                                       np.unique(model.spring_shape)).astype(np.int8)
    run.frames.write(k, k * run.scene.dt, st.x, st.v, fields,
                     kinematic=model.always_kinematic.astype(np.int8), **extra)
    if run.renderer is not None:
        run.renderer.render(k, k * run.scene.dt, st.x)


def _open_output(run: _Run):
    """Start writing: a new run clears (overwrite) and creates the folder and writes the
    scene, frame 0 and a checkpoint; a resumed one drops what followed its checkpoint.
    Returns the open step and Newton logs."""
    from .io.csv_log import NewtonLog, StepLog
    from .io.output_folder import prepare_output_folder
    from .io.resume import remove_temporaries
    from .io.vtk import FrameWriter, frame_compression
    from .scene import save_scene

    model, out = run.model, run.out
    if run.resume:
        remove_temporaries(out)
    else:
        prepare_output_folder(out, run.mode == "overwrite")
        save_scene(run.scene, out / "scene.toml")
    if model.dimension == 2:  # triangles (z = 0) and kinematic segments
        bodies = np.array([k == "triangles" for k in model.shape_kinds], dtype=bool)
        edges = model.surface_edges
        cells = dict(triangles=model.tri_elements,
                     segments=edges[~bodies[model.edge_shape]] if len(edges) else edges)
    else:
        cells = dict(tets=model.tets, triangles=model.kinematic_surface_triangles)
    run.frames = FrameWriter(out, **cells, body_id=model.vertex_shape,
                             compression_level=frame_compression(model.n_vertices))
    run.frames.series_interval = SERIES_SECONDS
    if run.render:
        from .io.render import LiveRenderer

        run.renderer = LiveRenderer(out, planes=run.scene.planes)
    keep = None
    if run.resume:
        run.frames.resume(run.first_step, lambda k: k * run.scene.dt)
        keep = (lambda row: int(row["step"]) <= run.first_step)
    else:
        _write_frame(run, 0)
        _checkpoint(run)
    run.step_log = StepLog(out / StepLog.FILE_NAME, keep_rows=keep)
    return run.step_log, NewtonLog(out / NewtonLog.FILE_NAME, keep_rows=keep)


def _warn_about(run: _Run, row: dict, k: int) -> None:
    """A warning for a step that did not converge (the first few of them)."""
    if row["converged"]:
        return
    run.warned += 1
    if run.warned > MAX_STEP_WARNINGS:
        return
    if row["hit_iteration_cap"]:
        why = f"hit the Newton iteration cap ({row['newton_iterations']})"
    else:
        why = (f"stopped after {row['newton_iterations']} Newton iterations: the line "
               "search found no decrease")
    more = ("; further ones are counted in run.json" if run.warned == MAX_STEP_WARNINGS
            else "")
    run.reporter.warn(f"warning: step {k} did not converge ({why}){more}")


def _checkpoint(run: _Run, logs=()) -> None:
    """Force the frames and rows written so far to disk, then write the checkpoint: the
    state a resumed run starts from, never ahead of the output it comes after."""
    from .io.checkpoint import write_checkpoint

    run.frames.sync()
    for log in logs:
        log.sync()
    write_checkpoint(run.out, run.sim.state, run.digest)
    run.checkpointed = time.perf_counter()


def _step_loop(run: _Run, step_log, newton_log, progress, stop) -> None:
    """Steps until the last one; KeyboardInterrupt once a Ctrl-C'd step is saved."""
    sim, n_steps, every = run.sim, run.n_steps, run.every
    while sim.state.step < n_steps:
        report = sim.step()
        row = report.row
        step_log.append_rows(report.rows)  # with adaptive steps, every attempt's
        newton_log.append_rows(report.newton)
        k = sim.state.step
        run.newton_total += sum(r.get("newton_iterations") or 0 for r in report.rows)
        _warn_about(run, row, k)
        for note in report.notes:  # the baselines' intersecting states
            run.reporter.warn(f"warning: step {k}: {note}")
        stopping = stop.requested and k < n_steps  # read once: Ctrl-C may come now
        framed = k % every == 0 or k == n_steps
        if framed:
            _write_frame(run, k)
        due = framed and time.perf_counter() - run.checkpointed >= CHECKPOINT_SECONDS
        if due or k == n_steps or stopping:  # stopping: resume here, not at the frame
            _checkpoint(run, (step_log, newton_log))
        progress.update(k, sim.state.time, row["newton_iterations"], row["contacts_total"])
        if stopping:
            raise KeyboardInterrupt


def _simulate(run: _Run) -> tuple[int, str | None, str | None]:
    """Open the output, run the steps; (exit status, failure for run.json, message)."""
    from .io.progress import RunProgress
    from .compiler.compiling import compile_seconds

    say = run.reporter.say
    step_log, newton_log = _open_output(run)
    say(f"ipcsim: {run.scene_name} -> {run.out}"
        + (f" (resuming after step {run.first_step})" if run.resume else ""))
    say("modelled terms: " + "; ".join(run.model.terms))
    say(f"linear solver: {run.sim.linear_solver.name}; threads: {run.sim.threads}")
    run.sim.on_iteration = run.reporter.on_iteration
    progress = RunProgress(run.first_step, run.n_steps, run.reporter.progress,
                           compiled=compile_seconds, first_time=run.sim.state.time,
                           end_time=run.n_steps * run.scene.dt)
    resume_collector()  # paused by the command while it started (start_up.py)
    with step_log, newton_log, StopRequest() as stop:
        try:
            _step_loop(run, step_log, newton_log, progress, stop)
        except SolverError as exc:
            step_log.append_rows(exc.attempts)  # the failed step's attempts, if adaptive
            newton_log.append_rows(exc.newton)
            tried = len(exc.attempts)
            return exc.exit_status, str(exc), (
                f"{exc}; frames and logs up to the last completed step are kept"
                + (f"; steps.csv ends with its {tried} attempt{'s' * (tried > 1)}"
                   if tried else ""))
        except KeyboardInterrupt:
            return _interrupted(run)
        except Exception:
            # a KeyboardInterrupt raised inside a C extension's call can come back as its
            # own error (pymetis: "RuntimeError: Caught an unknown exception!")
            if not stop.at_once:
                raise
            return _interrupted(run)
        finally:
            progress.close()  # before any message, so that it does not tangle with the bar
            if run.renderer is not None:
                run.renderer.close()
            run.frames.flush()  # the series names every frame written
    return 0, None, None


def _interrupted(run: _Run) -> tuple[int, str, str]:
    return 130, "interrupted", (f"interrupted after step {run.sim.state.step}; "
                                f"continue with: {resume_command(run)}")


def _toml_value(v) -> str:
    import tomli_w

    return " ".join(tomli_w.dumps({"v": v})[len("v = "):].split())


def resume_command(run: _Run) -> str:
    """The command line that continues this run, with the scene's overrides."""
    sets = "".join(f" --set {shlex.quote(f'{k}={_toml_value(v)}')}"
                   for k, v in run.scene.overrides.items())
    return f"ipcsim run {shlex.quote(run.scene_name)} -o {shlex.quote(str(run.out))}" \
           f"{sets} --resume"


def _run_info(run: _Run, status: int, failure, wall0: float, started: str) -> None:
    """Write run.json: this call's facts, with the totals of the whole run."""
    import json

    from .io.run_info import RUN_INFO_NAME, now_iso, peak_memory_mb, write_run_info
    from .compiler import aot
    from .compiler.compiling import compile_seconds

    out = run.out
    info = {"scene": run.scene_name, "output": str(out), "started": started,
            "modelled_terms": list(run.model.terms),
            "linear_solver": run.sim.linear_solver.name, "steps_planned": run.n_steps,
            "inputs_sha256": run.digest,
            "kernels": {"compiled_ahead_of_time": aot.compiled_folder() is not None,
                        "run_by_numba": aot.jit_kernels(),
                        "numba_compile_s": compile_seconds()}}
    if run.reporter.command:  # else write_run_info's own (this process's arguments)
        info["command"] = list(run.reporter.command)
    if run.scene.overrides:
        info["overrides"] = dict(run.scene.overrides)
    if run.resume:
        info["resumed_from_step"] = run.first_step
    wall = time.perf_counter() - wall0
    if run.resume and (out / RUN_INFO_NAME).is_file():
        try:  # wall time and start of the whole run, over all its invocations
            before = json.loads((out / RUN_INFO_NAME).read_text())
            wall += float(before.get("wall_s") or 0.0)
            info["started"] = before.get("started") or started
        except (OSError, ValueError, TypeError, AttributeError):
            pass
    logged = run.step_log.totals  # of the kept and the new steps
    info.update(finished=now_iso(), wall_s=wall, peak_memory_mb=peak_memory_mb(),
                steps_done=run.sim.state.step,
                newton_iterations=logged["newton_iterations"],
                steps_hitting_iteration_cap=logged["hit_iteration_cap"],
                steps_not_converged=logged["not_converged"],
                steps_accepted=logged["accepted"], steps_rejected=logged["rejected"],
                simulated_time=logged["simulated_time"],
                status="ok" if status == 0 else failure,
                outcome=run.sim.outcome if status in (0, 3) else failure)
    write_run_info(out, info)


def run(spec, out_dir=None, *, steps: int | None = None, mode: str = "new",
        render: bool = False, reporter: Reporter | None = None) -> RunResult:
    """Simulate ``spec`` (a ``SceneSpec``) and write its output folder ``out_dir``
    (default ``output/<scene-stem>``), exactly as ``ipcsim run`` does.

    ``steps``: stop after this step (default: the scene's last, ceil(duration/dt));
    ``mode``: "new" (refuses a folder that holds anything), "overwrite" (replaces a
    run there) or "resume" (continues the run there from its checkpoint); ``render``:
    also draw each frame as a PNG. Raises ``SceneError``/``OutputError`` (exit 2) before
    anything is written, ``RunFailed`` (3) when the simulation fails and
    ``RunInterrupted`` (130) on Ctrl-C, both after run.json is written."""
    from .io.run_info import now_iso

    steps = check_arguments(spec, out_dir, steps, mode, render, reporter)
    reporter = reporter or Reporter()
    wall0, started = time.perf_counter(), now_iso()
    r = _build(spec, out_dir, mode, steps, reporter)  # all checked before writing
    r.render = render
    try:
        status, failure, message = _simulate(r)
        _run_info(r, status, failure, wall0, started)
    except (OSError, OutputError) as exc:
        raise _output_error(r, exc) from None
    finally:
        r.lock.release()
    if status == 130:
        raise RunInterrupted(message)
    if status != 0:
        raise RunFailed(message, status)
    wall = time.perf_counter() - wall0
    reporter.say(f"done: {r.sim.state.step - r.first_step} steps, {r.newton_total} Newton "
                 f"iterations, {wall:.1f} s")
    if r.warned:
        reporter.warn(f"warning: {r.warned} steps did not converge (run.json: "
                      "steps_not_converged)")
    return RunResult(r.out, r.sim.state.step, r.n_steps, r.first_step, r.newton_total,
                     r.warned, wall, r.sim.state)


def check_arguments(spec, out_dir, steps, mode, render, reporter) -> int | None:
    """:func:`run`'s arguments checked before anything is built or written, as the
    command line checks its own (``ipcsim.arguments``): an ArgumentError (exit status 2,
    a ValueError) names the one that cannot be used. Returns ``steps`` as a number."""
    from .arguments import flag, folder_path, whole_number_at_least_1
    from .errors import ArgumentError
    from .scene import SceneSpec

    if not isinstance(spec, SceneSpec):
        raise ArgumentError("spec must be a SceneSpec (ipcsim.load_scene(path)), got "
                            f"{type(spec).__name__}")
    if out_dir is not None:
        folder_path(out_dir, "out_dir")
    if mode not in MODES:
        raise ArgumentError(f"mode must be one of {', '.join(MODES)}, got {excerpt(repr(mode))}")
    flag(render, "render")
    if reporter is not None and not isinstance(reporter, Reporter):
        raise ArgumentError("reporter must be an ipcsim.Reporter, got "
                            f"{type(reporter).__name__}")
    from .io.progress import MODES as PROGRESS

    if reporter is not None and reporter.progress not in PROGRESS:
        raise ArgumentError(f"reporter.progress must be one of {', '.join(PROGRESS)}, "
                            f"got {excerpt(repr(reporter.progress))}")
    if steps is None:
        return None
    try:
        return whole_number_at_least_1(steps)
    except ArgumentError as exc:
        raise ArgumentError(f"steps: {exc}") from None


def _output_error(run: _Run, exc: OSError | OutputError) -> OutputError:
    """A write that failed (a full disk, a folder made read-only) as one line: what
    could not be written, and how to go on."""
    from .io.checkpoint import CHECKPOINT_NAME

    if isinstance(exc, OSError):
        what = f"cannot write {exc.filename or run.out}: {exc.strerror or exc}"
    else:
        what = str(exc)
    if (run.out / CHECKPOINT_NAME).is_file():
        then = f"the folder is consistent up to its checkpoint; continue with: " \
               f"{resume_command(run)}"
    else:
        then = "nothing could be saved to resume from; run again"
    return OutputError(f"{what}; {then}")
