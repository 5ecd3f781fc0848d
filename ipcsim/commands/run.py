"""``ipcsim run SCENE``: simulate and write frames, logs and the resolved scene.

Everything is read, built and checked before the first byte is written: the scene, its
meshes, the simulation's start, the output folder and, for ``--resume``, the checkpoint
against the folder; so a bad input leaves every folder as it was, and ``--overwrite``
removes the old run only once the new one can start.

Nothing is lost on a crash: each step's CSV rows are flushed before the next step starts,
frames and the checkpoint are replaced atomically, and a checkpoint (with a frame, at most
every ``CHECKPOINT_SECONDS``, and at the end) first forces everything before it to disk. ``--resume`` continues from the checkpoint (after a kill, even SIGKILL, or a
full disk), and Ctrl-C stops after the current step with a fresh checkpoint (exit status
130).
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OutputError, SolverError


def frame_interval_for(scene) -> int:
    """About one frame per 0.01 s of simulated time, as the original (``playBackSpeed``
    below 1 writes denser frames)."""
    from ..io.vtk import frame_interval

    frame_dt = 0.01
    if scene.playback_speed < 1.0:
        frame_dt = max(scene.dt, min(0.01, scene.playback_speed * 0.03))
    return frame_interval(scene.dt, frame_dt)


class StopRequest:
    """The first Ctrl-C asks the run to stop after the current step; a second one stops
    at once (KeyboardInterrupt: the folder is still resumable from the last frame)."""

    def __init__(self):
        self.requested = False
        self._previous = None

    def _handle(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        print("\nipcsim: stopping after this step (Ctrl-C again to stop at once)",
              file=sys.stderr, flush=True)

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)
        return self

    def __exit__(self, *exc):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)


MAX_STEP_WARNINGS = 10  # non-converged steps named on the terminal; run.json counts all
# A checkpoint, which forces everything written before it to disk, at most this often
# (wall seconds; and always at the last step and on Ctrl-C). Between checkpoints frames
# and rows are replaced atomically but not forced to disk: a killed run resumes from the
# last checkpoint and computes at most this much again.
CHECKPOINT_SECONDS = 2.0


@dataclass
class _Run:
    """One invocation of ``ipcsim run``: what was built and checked before writing."""

    args: object
    scene: object
    model: object
    sim: object
    out: Path
    digest: str
    first_step: int = 0  # the checkpoint's step for --resume
    frames: object = None
    renderer: object = None
    warned: int = 0  # steps that did not converge, in this invocation
    newton_total: int = 0  # Newton iterations, in this invocation
    checkpointed: float = 0.0  # wall clock of the last checkpoint

    @property
    def resume(self) -> bool:
        return bool(getattr(self.args, "resume", False))

    @property
    def n_steps(self) -> int:
        """The last step of this invocation (``--steps``, at most the scene's)."""
        steps = self.args.steps
        return self.scene.n_steps if steps is None else min(steps, self.scene.n_steps)

    @property
    def every(self) -> int:
        return frame_interval_for(self.scene)


def _build(args) -> _Run:
    """Read, build and check everything; nothing is written yet."""
    from ..io.output_folder import default_output_folder, resolve_output_folder
    from ..scene.digest import inputs_digest
    from .common import load_and_build

    scene, model, sim = load_and_build(args.scene)
    resume = bool(getattr(args, "resume", False))
    mode = "resume" if resume else ("overwrite" if args.overwrite else "new")
    requested = args.output or default_output_folder(args.scene, scene.append_str)
    out = resolve_output_folder(requested, args.scene, mode=mode)
    run = _Run(args, scene, model, sim, out, inputs_digest(scene))
    if resume:
        run.first_step = _check_resume(run)
    return run


def _check_resume(run: _Run) -> int:
    """Validate the folder's checkpoint against the scene, the frames and the logs, then
    restore it into the simulation; returns its step. Nothing on disk changes."""
    from ..io.checkpoint import CheckpointError, read_checkpoint
    from ..io.resume import check_resume

    checkpoint = read_checkpoint(run.out)
    check_resume(run.out, checkpoint, inputs_sha256=run.digest,
                 n_vertices=len(run.model.mass), scene_steps=run.scene.n_steps,
                 frame_every=run.every, scene=run.args.scene)
    k = checkpoint["step"]
    if run.args.steps is not None and run.args.steps < k:
        raise CheckpointError(f"--steps {run.args.steps} lies before the checkpoint's step "
                              f"{k} in {run.out}")
    try:
        run.sim.restore(checkpoint)
    except ValueError as exc:
        raise CheckpointError(f"{run.out}: {exc}") from None
    return k


def _write_frame(run: _Run, k: int) -> None:
    st = run.sim.state
    run.frames.write(k, k * run.scene.dt, st.x, st.v,
                     kinematic=run.model.always_kinematic.astype(np.int8))
    if run.renderer is not None:
        run.renderer.render(k, k * run.scene.dt, st.x)


def _open_output(run: _Run):
    """Start writing: a new run clears (``--overwrite``) and creates the folder and writes
    the scene, frame 0 and a checkpoint; a resumed one drops what followed its
    checkpoint. Returns the open step and Newton logs."""
    from ..io.csv_log import NewtonLog, StepLog
    from ..io.output_folder import prepare_output_folder
    from ..io.resume import remove_temporaries
    from ..io.vtk import FrameWriter
    from ..scene import save_scene

    model, out = run.model, run.out
    if run.resume:
        remove_temporaries(out)
    else:
        prepare_output_folder(out, run.args.overwrite)
        save_scene(run.scene, out / "scene.toml")
    run.frames = FrameWriter(out, tets=model.tets, triangles=model.kinematic_surface_triangles,
                             body_id=model.vertex_shape)
    if getattr(run.args, "render", False):
        from ..io.render import LiveRenderer

        run.renderer = LiveRenderer(out, planes=run.scene.planes)
    keep = None
    if run.resume:
        run.frames.resume(run.first_step, lambda k: k * run.scene.dt)
        keep = (lambda row: int(row["step"]) <= run.first_step)
    else:
        _write_frame(run, 0)
        _checkpoint(run)
    return (StepLog(out / StepLog.FILE_NAME, keep_rows=keep),
            NewtonLog(out / NewtonLog.FILE_NAME, keep_rows=keep))


def _warn_about(run: _Run, row: dict, k: int) -> None:
    """A terminal warning for a step that did not converge (the first few of them)."""
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
    print(f"warning: step {k} did not converge ({why}){more}", file=sys.stderr, flush=True)


def _checkpoint(run: _Run, logs=()) -> None:
    """Force the frames and rows written so far to disk, then write the checkpoint: the
    state a resumed run starts from, never ahead of the output it comes after."""
    from ..io.checkpoint import write_checkpoint

    run.frames.sync()
    for log in logs:
        log.sync()
    write_checkpoint(run.out, run.sim.state, run.digest)
    run.checkpointed = time.perf_counter()


def _step_loop(run: _Run, step_log, newton_log, progress, stop) -> None:
    """Steps until the last one; KeyboardInterrupt once a Ctrl-C'd step is saved."""
    sim, n_steps = run.sim, run.n_steps
    while sim.state.step < n_steps:
        report = sim.step()
        row = report.row
        step_log.append(row)
        for it in report.newton:
            newton_log.append(it)
        k = sim.state.step
        run.newton_total += row["newton_iterations"]
        _warn_about(run, row, k)
        for note in report.notes:  # the baselines' intersecting states
            print(f"warning: step {k}: {note}", file=sys.stderr)
        stopping = stop.requested and k < n_steps  # read once: Ctrl-C may come now
        framed = k % run.every == 0 or k == n_steps
        if framed:
            _write_frame(run, k)
        due = framed and time.perf_counter() - run.checkpointed >= CHECKPOINT_SECONDS
        if due or k == n_steps or stopping:  # stopping: resume here, not at the frame
            _checkpoint(run, (step_log, newton_log))
        progress.update(k, k * run.scene.dt, row["newton_iterations"], row["contacts_total"])
        if stopping:
            raise KeyboardInterrupt


def _simulate(run: _Run, say) -> tuple[int, str | None, str | None]:
    """Open the output, run the steps; (exit status, failure for run.json, message)."""
    from ..kernels.compiling import compile_seconds
    from .progress import RunProgress

    args = run.args
    step_log, newton_log = _open_output(run)
    say(f"ipcsim: {args.scene} -> {run.out}" + (f" (resuming after step {run.first_step})"
                                                if run.resume else ""))
    say("modelled terms: " + "; ".join(run.model.terms))
    say(f"linear solver: {run.sim.linear_solver.name}; threads: {run.sim.threads}")
    if args.verbose and not args.quiet:
        run.sim.on_iteration = lambda it: print(
            f"  step {it['step']} it {it['iteration']}: alpha={it['alpha']:.3g} "
            f"|p|={it['step_inf_norm']:.3e} tol={it['tolerance']:.3e} "
            f"contacts={it['contacts_total']} kappa={it['kappa']:.3g}", flush=True)
    progress = RunProgress(run.first_step, run.n_steps, RunProgress.mode_for(args.quiet),
                           compiled=compile_seconds)
    with step_log, newton_log, StopRequest() as stop:
        try:
            _step_loop(run, step_log, newton_log, progress, stop)
        except SolverError as exc:
            return exc.exit_status, str(exc), (f"{exc}; frames and logs up to the last "
                                               "completed step are kept")
        except KeyboardInterrupt:
            return 130, "interrupted", (f"interrupted after step {run.sim.state.step}; "
                                        f"continue with: {_resume_command(run)}")
        finally:
            progress.close()  # before any message, so that it does not tangle with the bar
            if run.renderer is not None:
                run.renderer.close()
    return 0, None, None


def _resume_command(run: _Run) -> str:
    return f"ipcsim run {run.args.scene} -o {run.out} --resume"


def _run_info(run: _Run, status: int, failure, wall0: float, started: str) -> None:
    """Write run.json: this invocation's facts, with the totals of the whole run."""
    import json

    from ..io.csv_log import StepLog, read_csv
    from ..io.run_info import RUN_INFO_NAME, now_iso, write_run_info

    out = run.out
    info = {"scene": str(run.args.scene), "output": str(out), "started": started,
            "command": sys.argv, "modelled_terms": list(run.model.terms),
            "linear_solver": run.sim.linear_solver.name, "steps_planned": run.n_steps,
            "inputs_sha256": run.digest}
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
    logged = read_csv(out / StepLog.FILE_NAME)  # totals of the kept and the new steps
    converged = logged.get("converged", np.ones(0))
    info.update(finished=now_iso(), wall_s=wall, steps_done=run.sim.state.step,
                newton_iterations=int(np.sum(logged.get("newton_iterations", 0))),
                steps_hitting_iteration_cap=int(np.sum(logged.get("hit_iteration_cap", 0))),
                steps_not_converged=int(np.sum(converged == 0)),
                status="ok" if status == 0 else failure,
                outcome=run.sim.outcome if status in (0, 3) else failure)
    write_run_info(out, info)


def main(args) -> int:
    from ..io.run_info import now_iso

    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    wall0, started = time.perf_counter(), now_iso()
    if not args.quiet:
        _tell_when_compiling()
    run = _build(args)  # everything is checked before the first byte is written
    try:
        status, failure, message = _simulate(run, say)
        if message is not None:
            print(f"ipcsim: {message}", file=sys.stderr)
        _run_info(run, status, failure, wall0, started)
    except (OSError, OutputError) as exc:
        raise _output_error(run, exc) from None
    if status == 0:
        say(f"done: {run.sim.state.step - run.first_step} steps, {run.newton_total} Newton "
            f"iterations, {time.perf_counter() - wall0:.1f} s")
        if run.warned:
            print(f"warning: {run.warned} steps did not converge (run.json: "
                  "steps_not_converged)", file=sys.stderr)
    return status


def _tell_when_compiling() -> None:
    """Say once why a first run after installing is slow (numba compiles the kernels)."""
    from ..kernels.compiling import when_compiling_starts

    when_compiling_starts(lambda: print(
        "ipcsim: compiling the numba kernels for this machine (once after installing; "
        "later runs start at once)", file=sys.stderr, flush=True))


def _output_error(run: _Run, exc: OSError | OutputError) -> OutputError:
    """A write that failed (a full disk, a folder made read-only) as one line: what
    could not be written, and how to go on."""
    from ..io.checkpoint import CHECKPOINT_NAME

    if isinstance(exc, OSError):
        what = f"cannot write {exc.filename or run.out}: {exc.strerror or exc}"
    else:
        what = str(exc)
    if (run.out / CHECKPOINT_NAME).is_file():
        then = f"the folder is consistent up to its checkpoint; continue with: " \
               f"{_resume_command(run)}"
    else:
        then = "nothing could be saved to resume from; run again"
    return OutputError(f"{what}; {then}")
