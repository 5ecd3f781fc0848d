"""``ipcsim check SCENE``: read a scene, build its model and print what it contains.

Prints the scene's warnings and ignored (viewer-only) keys, the builder's warnings, the
terms the simulation will assemble, and counts. Exit status 0; a bad scene or mesh raises
a typed error that ``ipcsim.cli`` reports as ``path:line: message`` (status 2).
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
    from ..model.builder import build_model
    from ..scene import load_scene

    scene = load_scene(Path(args.scene))
    model = build_model(scene)
    report(scene, model)
    return 0
