"""``ipcsim check SCENE``: read a scene, build its model and print what it contains.
``ipcsim check --frames OUT``: verify every written frame of a run with exact predicates.

The scene report prints the scene's warnings and ignored (viewer-only) keys, the builder's
warnings, the terms the simulation will assemble, and counts. Exit status 0; a bad scene
or mesh raises a typed error that ``ipcsim.cli`` reports as ``path:line: message`` (2).

The frame check needs nothing but the output folder: it reads ``frames/series.pvd``, and
for every frame tests every surface edge against every surface triangle it shares no
vertex with (exact segment–triangle predicate) and every tet's orientation. Exit status 0
when all frames are intersection- and inversion-free, 1 when some are not.
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


def check_frames(folder: Path, out=None, totals: dict | None = None) -> int:
    """Exact intersection and inversion check of every frame of a run. ``totals``, when
    given, receives the counts summed over frames: ``intersections``, ``inverted_tets``,
    ``below_plane``."""
    import meshio
    import numpy as np

    from ..contact.intersection import check_frame
    from ..errors import IpcsimError
    from ..io.vtk import SERIES_NAME, read_series
    from ..model.surface import boundary_triangles

    out = out or sys.stdout
    pvd = Path(folder) / "frames" / SERIES_NAME
    if not pvd.is_file():
        raise IpcsimError(f"{folder}: no frames to check ({pvd} not found)")
    planes, self_collision = _scene_of_run(Path(folder))
    if not self_collision:
        out.write("the run's scene has self collision off: bodies may pass through each other, "
                  "so only inverted tets and plane sides are checked\n")
    bad = 0
    counts = {"intersections": 0, "inverted_tets": 0, "below_plane": 0}
    series = read_series(pvd)
    surface = None
    for time, vtu in series:
        try:
            mesh = meshio.read(vtu)
        except Exception as exc:  # meshio raises many kinds; the frame is unreadable
            raise IpcsimError(f"{vtu}: cannot read frame ({exc})") from None
        tets = mesh.cells_dict.get("tetra", np.zeros((0, 4), dtype=np.int64))
        if surface is None:  # connectivity is the same in every frame of a run
            surface = np.concatenate([boundary_triangles(tets).reshape(-1, 3),
                                      mesh.cells_dict.get("triangle", np.zeros((0, 3)))])
            surface = surface.astype(np.int64)
        result = check_frame(mesh.points, tets.astype(np.int64),
                             surface if self_collision else surface[:0])
        problems = [] if result.ok else [result.summary()]
        counts["intersections"] += max(result.n_intersections, 0)
        counts["inverted_tets"] += max(result.n_inverted, 0)
        if planes is not None and len(tets):
            # simulated vertices must stay strictly on the positive side of every plane
            origins, normals = planes
            x = mesh.points[np.unique(tets)]
            below = int((np.einsum("vk,pk->vp", x, normals)
                         - np.einsum("pk,pk->p", origins, normals) <= 0.0).any(axis=1).sum())
            counts["below_plane"] += below
            if below:
                problems.append(f"{below} vertices on or below a plane")
        if problems:
            bad += 1
            out.write(f"{vtu.name} (t={time:g} s): {'; '.join(problems)}\n")
    if totals is not None:
        totals.update(counts)
    clean = "no intersection and no inverted tet" if self_collision else "no inverted tet"
    out.write(f"checked {len(series)} frames: "
              + (f"{clean}\n" if bad == 0 else f"{bad} frames with problems\n"))
    return 0 if bad == 0 else 1


def _scene_of_run(folder: Path):
    """From the run's scene.toml: ((origins, normals) of its planes or None, whether self
    collision is on). Without a scene.toml: no planes, self collision on."""
    import numpy as np

    from ..scene import load_scene

    scene_file = folder / "scene.toml"
    if not scene_file.is_file():
        return None, True
    scene = load_scene(scene_file)
    planes = None
    if scene.planes:
        planes = (np.array([p.origin for p in scene.planes], dtype=float),
                  np.array([p.normal for p in scene.planes], dtype=float))
    return planes, scene.self_collision


def main(args) -> int:
    from ..model.builder import build_model
    from ..scene import load_scene

    if getattr(args, "frames", None):
        return check_frames(Path(args.frames))
    if not args.scene:
        from ..errors import IpcsimError

        raise IpcsimError("check needs a scene file or --frames OUTPUT_FOLDER")
    scene = load_scene(Path(args.scene))
    model = build_model(scene)
    report(scene, model)
    return 0
