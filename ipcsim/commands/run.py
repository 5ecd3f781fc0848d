"""``ipcsim run SCENE``: simulate and write frames, logs and the resolved scene.

Nothing is lost on a crash: each step's CSV rows are flushed before the next step starts,
frames and the checkpoint are replaced atomically, and the checkpoint is written after
its frame. ``--resume`` continues from the checkpoint (after a kill, even SIGKILL), and
Ctrl-C stops after the current step with a fresh checkpoint (exit status 130).
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

from ..errors import SolverError


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


def _prepare_resume(args, scene, out: Path, sim) -> int:
    """Check that OUT was started with this scene and restore its checkpoint; returns
    the step to continue from."""
    from ..io.checkpoint import CheckpointError, read_checkpoint
    from ..scene import load_scene

    if not out.is_dir():
        raise CheckpointError(f"{out}: no such output folder to resume")
    saved = out / "scene.toml"
    if not saved.is_file():
        raise CheckpointError(f"{out}: not a run folder (no scene.toml)")
    if load_scene(saved) != scene:
        raise CheckpointError(f"{args.scene} is not the scene the run in {out} was started "
                              f"with ({saved}); resume with that scene or run afresh")
    checkpoint = read_checkpoint(out)
    try:
        sim.restore(checkpoint)
    except ValueError as exc:
        raise CheckpointError(f"{out}: {exc}") from None
    return checkpoint["step"]


def main(args) -> int:
    from ..io.checkpoint import CheckpointError, write_checkpoint
    from ..io.csv_log import NewtonLog, StepLog, read_csv
    from ..io.output_folder import default_output_folder, prepare_output_folder
    from ..io.run_info import RUN_INFO_NAME, now_iso, write_run_info
    from ..io.vtk import FrameWriter
    from ..model.builder import build_model
    from ..scene import load_scene, save_scene
    from ..simulation import Simulation
    from .progress import RunProgress

    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    wall0 = time.perf_counter()
    started = now_iso()
    scene = load_scene(args.scene)
    for w in scene.warnings:
        print(w, file=sys.stderr)
    model = build_model(scene)
    for w in getattr(model, "warnings", ()):
        print(w, file=sys.stderr)
    sim = Simulation(model)

    out = Path(args.output) if args.output else default_output_folder(args.scene)
    resume = getattr(args, "resume", False)
    if resume:
        first_step = _prepare_resume(args, scene, out, sim)
    else:
        first_step = 0
        out = prepare_output_folder(out, args.overwrite)
        save_scene(scene, out / "scene.toml")
    say(f"ipcsim: {args.scene} -> {out}" + (f" (resuming after step {first_step})"
                                            if resume else ""))
    say("modelled terms: " + "; ".join(model.terms))
    say(f"linear solver: {sim.linear_solver.name}")

    n_steps = scene.n_steps if args.steps is None else min(args.steps, scene.n_steps)
    every = frame_interval_for(scene)
    frames = FrameWriter(out, tets=model.tets, triangles=model.kinematic_surface_triangles,
                         body_id=model.vertex_shape)
    kinematic0 = model.always_kinematic.astype(np.int8)
    renderer = None
    if getattr(args, "render", False):
        from ..io.render import LiveRenderer

        renderer = LiveRenderer(out)

    def write_frame(k):
        frames.write(k, k * scene.dt, sim.state.x, sim.state.v, kinematic=kinematic0)
        if renderer is not None:
            renderer.render(k, k * scene.dt, sim.state.x)

    if resume:
        frames.resume(first_step, lambda k: k * scene.dt)
        keep = (lambda row: int(row["step"]) <= first_step)
    else:
        write_frame(0)
        write_checkpoint(out, sim.state)
        keep = None

    info = {"scene": str(args.scene), "output": str(out), "started": started,
            "command": sys.argv, "modelled_terms": list(model.terms),
            "linear_solver": sim.linear_solver.name, "steps_planned": n_steps}
    if resume:
        info["resumed_from_step"] = first_step
    status, failure = 0, None
    steps_done, newton_total = 0, 0
    progress = RunProgress(first_step, n_steps, RunProgress.mode_for(args.quiet))
    if args.verbose and not args.quiet:
        sim.on_iteration = lambda it: print(
            f"  step {it['step']} it {it['iteration']}: alpha={it['alpha']:.3g} "
            f"|p|={it['step_inf_norm']:.3e} tol={it['tolerance']:.3e} "
            f"contacts={it['contacts_total']} kappa={it['kappa']:.3g}", flush=True)
    try:
        step_log = StepLog(out / StepLog.FILE_NAME, keep_rows=keep)
        newton_log = NewtonLog(out / NewtonLog.FILE_NAME, keep_rows=keep)
    except ValueError as exc:
        raise CheckpointError(str(exc)) from None
    with step_log, newton_log, StopRequest() as stop:
        try:
            while sim.state.step < n_steps:
                report = sim.step()
                row = report.row
                step_log.append(row)
                for it in report.newton:
                    newton_log.append(it)
                steps_done += 1
                newton_total += row["newton_iterations"]
                k = sim.state.step
                for note in report.notes:  # the baselines' intersecting states
                    print(f"warning: step {k}: {note}", file=sys.stderr)
                if row["hit_iteration_cap"]:
                    print(f"warning: step {k} hit the Newton iteration cap "
                          f"({row['newton_iterations']}) without converging", file=sys.stderr)
                stopping = stop.requested and k < n_steps  # read once: Ctrl-C may come now
                if k % every == 0 or k == n_steps:
                    write_frame(k)
                    write_checkpoint(out, sim.state)
                elif stopping:
                    write_checkpoint(out, sim.state)  # resume from this step, not the frame
                progress.update(k, k * scene.dt, row["newton_iterations"],
                                row["contacts_total"])
                if stopping:
                    raise KeyboardInterrupt
        except SolverError as exc:
            status, failure = exc.exit_status, str(exc)
            message = f"{exc}; frames and logs up to the last completed step are kept"
        except KeyboardInterrupt:
            status, failure = 130, "interrupted"
            message = (f"interrupted after step {sim.state.step}; continue with: ipcsim run "
                       f"{args.scene} -o {out} --resume")
        finally:
            progress.close()  # before any message, so that it does not tangle with the bar
            if renderer is not None:
                renderer.close()
    if failure is not None:
        print(f"ipcsim: {message}", file=sys.stderr)

    wall = time.perf_counter() - wall0
    if resume and (out / RUN_INFO_NAME).is_file():
        import json

        try:  # wall time and start of the whole run, over all its invocations
            before = json.loads((out / RUN_INFO_NAME).read_text())
            wall += before.get("wall_s") or 0.0
            info["started"] = before.get("started") or started
        except (OSError, ValueError):
            pass
    logged = read_csv(out / StepLog.FILE_NAME)  # totals of the kept and the new steps
    info.update(finished=now_iso(), wall_s=wall, steps_done=sim.state.step,
                newton_iterations=int(np.sum(logged.get("newton_iterations", 0))),
                steps_hitting_iteration_cap=int(np.sum(logged.get("hit_iteration_cap", 0))),
                status="ok" if status == 0 else failure,
                outcome=sim.outcome if status in (0, 3) else failure)
    write_run_info(out, info)
    if status == 0:
        say(f"done: {steps_done} steps, {newton_total} Newton iterations, {wall:.1f} s")
    return status

