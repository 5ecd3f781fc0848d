"""``ipcsim run SCENE``: simulate and write frames, logs and the resolved scene."""

from __future__ import annotations

import sys
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


def main(args) -> int:
    from ..io.csv_log import NewtonLog, StepLog
    from ..io.output_folder import default_output_folder, prepare_output_folder
    from ..io.run_info import now_iso, write_run_info
    from ..io.vtk import FrameWriter
    from ..model.builder import build_model
    from ..scene import load_scene, save_scene
    from ..simulation import Simulation

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
    out = prepare_output_folder(out, args.overwrite)
    save_scene(scene, out / "scene.toml")
    say(f"ipcsim: {args.scene} -> {out}")
    say("modelled terms: " + "; ".join(model.terms))
    say(f"linear solver: {sim.linear_solver.name}")

    n_steps = scene.n_steps if args.steps is None else min(args.steps, scene.n_steps)
    every = frame_interval_for(scene)
    frames = FrameWriter(out, tets=model.tets, triangles=model.kinematic_surface_triangles,
                         body_id=model.vertex_shape)
    kinematic0 = model.always_kinematic.astype(np.int8)
    frames.write(0, 0.0, sim.state.x, sim.state.v, kinematic=kinematic0)

    info = {"scene": str(args.scene), "output": str(out), "started": started,
            "command": sys.argv, "modelled_terms": list(model.terms),
            "linear_solver": sim.linear_solver.name, "steps_planned": n_steps}
    status, failure = 0, None
    steps_done, newton_total, capped = 0, 0, 0
    with StepLog(out / "steps.csv") as step_log, NewtonLog(out / "newton.csv") as newton_log:
        try:
            for _ in range(n_steps):
                report = sim.step()
                row = report["step"]
                step_log.append(row)
                for it in report["newton"]:
                    newton_log.append(it)
                steps_done += 1
                newton_total += row["newton_iterations"]
                if row["hit_iteration_cap"]:
                    capped += 1
                    print(f"warning: step {row['step']} hit the Newton iteration cap "
                          f"({row['newton_iterations']}) without converging", file=sys.stderr)
                if args.verbose:
                    for it in report["newton"]:
                        say(f"  step {row['step']} it {it['iteration']}: "
                            f"alpha={it['alpha']:.3g} |p|={it['step_inf_norm']:.3e} "
                            f"tol={it['tolerance']:.3e} contacts={it['contacts_total']}")
                k = sim.state.step
                if k % every == 0 or k == n_steps:
                    frames.write(k, k * scene.dt, sim.state.x, sim.state.v,
                                 kinematic=kinematic0)
                if not args.quiet and (k % max(1, n_steps // 20) == 0 or k == n_steps):
                    say(f"step {k}/{n_steps}  t={k * scene.dt:.4g}s  "
                        f"newton={row['newton_iterations']}  contacts={row['contacts_total']}  "
                        f"wall={time.perf_counter() - wall0:.1f}s")
        except SolverError as exc:
            status, failure = exc.exit_status, str(exc)
            print(f"ipcsim: {exc}", file=sys.stderr)
        except KeyboardInterrupt:
            status, failure = 130, "interrupted"
            print("ipcsim: interrupted; frames written so far are complete", file=sys.stderr)

    wall = time.perf_counter() - wall0
    info.update(finished=now_iso(), wall_s=wall, steps_done=steps_done,
                newton_iterations=newton_total, steps_hitting_iteration_cap=capped,
                status="ok" if status == 0 else failure)
    write_run_info(out, info)
    say(f"done: {steps_done} steps, {newton_total} Newton iterations, {wall:.1f} s")
    return status
