"""``ipcsim check SCENE``: read a scene, build its model and print what it contains.
``ipcsim check --frames OUT``: verify every written frame of a run with exact predicates.

The scene report prints the scene's warnings and ignored (viewer-only) keys, the builder's
warnings, the terms the simulation will assemble, and counts. Exit status 0; a bad scene
or mesh raises a typed error that ``ipcsim.cli`` reports as ``path:line: message`` (2).

The scene check sets the simulation up as ``run`` does, so it refuses what ``run`` refuses
(shapes that intersect or touch at the start, a vertex on or below a plane, an inverted
tet, a linear solver that is not installed).

The frame check is ``contact.frame_check.check_frames``.
"""

from __future__ import annotations

import sys
from pathlib import Path


def _kinds_text(kinds: dict[str, int]) -> str:
    total = sum(kinds.values())
    return f"{total} (" + ", ".join(f"{v} {k}" for k, v in kinds.items()) + ")"


def report(scene, model, out=None) -> None:
    """Write the check report of a built model to ``out`` (default stdout)."""
    out = out or sys.stdout
    w = out.write
    w(f"scene: {scene.source or '<in memory>'}\n")
    for msg in scene.warnings:  # the readers format these as `path:line: warning: ...`
        w(f"{msg}\n" if "warning" in msg else f"warning: {msg}\n")
    if scene.ignored:
        w(f"ignored (viewer-only or no-op) keys: {', '.join(scene.ignored)}\n")
    for msg in model.warnings:
        w(f"warning: {msg}\n")
    w("terms:\n")
    for term in model.terms:
        w(f"  - {term}\n")
    kinematic = int(model.kinematic_mask_at(0.0).sum())
    rows = [
        ("shapes", _kinds_text(model.summary()["shapes"])),
        ("vertices", model.n_vertices),
        ("tets", model.n_tets),
        ("surface triangles", len(model.surface_triangles)),
        ("surface edges", len(model.surface_edges)),
        ("collision vertices", len(model.surface_vertices)),
        ("kinematic vertices (t=0)", kinematic),
        ("planes", model.n_planes),
        ("l (rest bbox diagonal)", f"{model.bbox_diagonal:.6g} m"),
        ("d-hat", f"{model.dhat:.6g} m"),
        ("time step", f"{scene.dt:g} s"),
        ("steps", scene.n_steps),
    ]
    width = max(len(name) for name, _ in rows)
    w("counts:\n")
    for name, value in rows:
        w(f"  {name:<{width}}  {value}\n")


def main(args) -> int:
    from ..contact.frame_check import check_frames
    from ..errors import IpcsimError
    from .common import load_and_build
    from .run import overrides_of

    overrides = overrides_of(args.set)
    if getattr(args, "frames", None):
        if overrides and not args.scene:
            raise IpcsimError("check --frames: --set changes a scene, and none was given: "
                              f"ipcsim check SCENE --frames {args.frames} --set ...")
        scene = None
        if args.scene:
            from ..scene import load_scene

            scene = load_scene(Path(args.scene), overrides)
        return check_frames(Path(args.frames), scene=scene)
    if not args.scene:
        raise IpcsimError("check needs a scene file or --frames OUTPUT_FOLDER")
    # the simulation is set up too: it refuses what `run` would (intersecting or touching
    # shapes at the start, a vertex on or below a plane, an inverted tet, a missing solver)
    scene, model, _ = load_and_build(args.scene, overrides=overrides,
                                     warn=lambda message: None)
    report(scene, model)
    return 0
