"""A run's frames verified with exact predicates (``ipcsim check --frames OUT``).

``check_frames`` reads ``frames/series.pvd`` and, for every frame, tests every surface
edge against every surface triangle it shares no vertex with (exact segment–triangle
predicate); where none crosses, whether a part of the mesh lies inside another's closed
surface (``intersection.find_containments``); every tet's orientation; and the simulated
vertices against the scene's planes (the run's scene.toml, or the scene given, which must
be the run's). Pairs between two kinematic obstacles are not judged (IPC promises nothing
there) and are mentioned in a note. It returns 0 when all frames are intersection- and
inversion-free, 1 when some are not; a damaged frame or series is a typed error.
"""

from __future__ import annotations

import sys
from pathlib import Path


def check_frames(folder: Path, out=None, totals: dict | None = None, scene=None) -> int:
    """Exact intersection and inversion check of every frame of a run, against its
    scene (``scene``, else its scene.toml: :func:`run_scene`). ``totals``, when given,
    receives the counts summed over frames: ``intersections``, ``contained`` (parts
    inside another), ``inverted_tets``, ``below_plane`` (and ``obstacle_contacts``, which
    are not problems)."""
    from ..errors import IpcsimError
    from ..io.vtk import SERIES_NAME, FrameError, read_frame, read_series

    out = out or sys.stdout
    pvd = Path(folder) / "frames" / SERIES_NAME
    if not pvd.is_file():
        raise IpcsimError(f"{folder}: no frames to check ({pvd} not found)")
    scene = run_scene(Path(folder), scene)
    planes, self_collision = _scene_of_run(Path(folder), scene)
    series = read_series(pvd)
    if not series:
        raise FrameError(f"{pvd}: lists no frames")
    if not self_collision:
        out.write("the run's scene has self collision off: bodies may pass through each other, "
                  "so only inverted tets and plane sides are checked\n")
    bad, checker = 0, None
    counts = {"intersections": 0, "contained": 0, "inverted_tets": 0, "below_plane": 0,
              "obstacle_contacts": 0}
    for time, vtu in series:
        mesh = read_frame(vtu)
        if checker is None:  # connectivity is the same in every frame of a run
            checker = (_PlanarFrameChecker(mesh, scene) if scene.dimension == 2
                       else _FrameChecker(mesh, planes, self_collision))
        problems = checker.check(mesh, vtu, counts, time)
        if problems:
            bad += 1
            out.write(f"{vtu.name} (t={time:g} s): {'; '.join(problems)}\n")
    if totals is not None:
        totals.update(counts)
    if counts["obstacle_contacts"]:
        out.write(f"note: kinematic obstacles touch or overlap each other "
                  f"({counts['obstacle_contacts']} edge-triangle pairs over all frames); IPC "
                  "neither prevents nor promises anything between two obstacles\n")
    element = "triangle" if scene.dimension == 2 else "tet"
    clean = (f"no intersection and no inverted {element}" if self_collision
             else f"no inverted {element}")
    out.write(f"checked {len(series)} frames: "
              + (f"{clean}\n" if bad == 0 else f"{bad} frames with problems\n"))
    return 0 if bad == 0 else 1


def _frame_positions(mesh, vtu, n: int):
    """(the frame's positions, [its non-finite vertices' problem] or []); a frame of
    another vertex count than the run's first is an error."""
    import numpy as np

    from ..io.vtk import FrameError

    x = np.asarray(mesh.points, dtype=np.float64)
    if len(x) != n:
        raise FrameError(f"{vtu}: {len(x)} vertices, the run's first frame has {n}")
    bad = int((~np.isfinite(x).all(axis=1)).sum())
    return x, ([f"{bad} vertices with non-finite coordinates"] if bad else [])

def _tally(counts: dict, between_obstacles, inverted: int, pairs_are: str,
           elements_are: str) -> tuple[int, list[str]]:
    """Count a frame's crossing pairs (those between two obstacles apart: they may
    cross) and inverted elements into ``counts``; (crossing pairs, the problem line)."""
    counts["obstacle_contacts"] += int(between_obstacles.sum())
    n_pairs = int((~between_obstacles).sum())
    counts["intersections"] += n_pairs
    counts["inverted_tets"] += inverted
    if not (n_pairs or inverted):
        return n_pairs, []
    return n_pairs, [f"{n_pairs} {pairs_are}; {inverted} inverted {elements_are}"]


def _on_or_beyond(points, origins, normals) -> int:
    """How many points lie on or behind at least one of the planes (lines in 2D)."""
    import numpy as np

    offsets = points @ normals.T - np.einsum("pk,pk->p", origins, normals)
    return int((offsets <= 0.0).any(axis=1).sum())



class _FrameChecker:
    """The fixed mesh of a run's frames (from the first one) and what is judged on it:
    edge-triangle pairs of which at least one side is a simulated body (pairs between two
    kinematic obstacles are counted apart), tet orientations, and simulated vertices
    against the scene's planes."""

    def __init__(self, mesh, planes, self_collision: bool):
        import numpy as np

        from .intersection import edges_of_triangles
        from ..model.surface import boundary_triangles

        self.n = len(mesh.points)
        cells = {c.type: np.asarray(c.data, dtype=np.int64) for c in mesh.cells}
        self.tets = cells.get("tetra", np.zeros((0, 4), np.int64)).reshape(-1, 4)
        surface = np.concatenate([boundary_triangles(self.tets),
                                  cells.get("triangle", np.zeros((0, 3), np.int64))])
        self.triangles = surface if self_collision else surface[:0]
        self.edges = edges_of_triangles(self.triangles)
        body = np.asarray(mesh.point_data.get("body_id", np.zeros(self.n)), dtype=np.int64)
        kinematic = np.asarray(mesh.point_data.get("kinematic", np.zeros(self.n))) != 0
        body = body.reshape(self.n, -1)[:, 0]
        kinematic = kinematic.reshape(self.n, -1)[:, 0]
        # an obstacle: a body whose every vertex is prescribed
        ids, inverse = np.unique(body, return_inverse=True)
        moving = np.bincount(inverse, weights=~kinematic, minlength=len(ids)) > 0
        self.obstacle_vertex = ~moving[inverse]
        self.body = body
        self.solids = self.moving = None
        if self_collision:  # parts inside others, by the intersection check's own rules
            from .intersection import moving_parts, solids_of

            self.solids = solids_of(self.n, self.tets, surface)
            self.moving = moving_parts(self.solids, self.obstacle_vertex)
        self.planes = planes
        simulated = np.zeros(self.n, dtype=bool)
        simulated[self.tets.ravel()] = True
        self.plane_vertices = np.flatnonzero(simulated & ~kinematic)

    def check(self, mesh, vtu, counts: dict, time: float = 0.0) -> list[str]:
        """The problems of one frame (empty when it is clean); ``counts`` accumulates."""

        from .intersection import find_intersections, inverted_tets

        x, problems = _frame_positions(mesh, vtu, self.n)
        if problems:
            return problems
        pairs = find_intersections(x, self.edges, self.triangles)
        between_obstacles = (self.obstacle_vertex[self.edges[pairs[:, 0]]].all(axis=1)
                             & self.obstacle_vertex[self.triangles[pairs[:, 1]]].all(axis=1))
        n_pairs, problems = _tally(counts, between_obstacles, len(inverted_tets(x, self.tets)),
                                   "intersecting edge-triangle pairs", "tets")
        if self.solids is not None and n_pairs == 0:  # else a part is partly inside
            problems += self._contained(x, counts)
        if self.planes is not None and len(self.plane_vertices):
            # simulated vertices must stay strictly on the positive side of every plane
            origins, normals = self.planes
            below = _on_or_beyond(x[self.plane_vertices], origins, normals)
            counts["below_plane"] += below
            if below:
                problems.append(f"{below} vertices on or below a plane")
        return problems

    def _contained(self, x, counts: dict) -> list[str]:
        """Parts of the mesh that lie wholly inside another's closed surface (no surface
        crosses: ``contact.intersection.find_containments``), unless both are obstacles."""
        from .intersection import find_containments

        pairs = find_containments(x, self.solids)
        pairs = pairs[self.moving[self.solids.labels[pairs]].any(axis=1)] if len(pairs) \
            else pairs
        counts["contained"] += len(pairs)
        if not len(pairs):
            return []
        inner, outer = (int(self.body[v]) for v in pairs[0])
        return [f"{len(pairs)} parts inside another's closed surface (first: a part of body "
                f"{inner} inside body {outer})"]


class _PlanarFrameChecker:
    """A 2D run's frames (z = 0): no two boundary edges (of the triangles, and the
    kinematic segments) that share a point, unless both are kinematic or, with self
    collision off, of one body; no inverted or flat triangle (a mass-spring body's may
    turn, as the lecture's do: they only draw it); no simulated vertex on or
    beyond a line, the moving lines where the frame says the run had them (its field
    data ``plane_origins``), else where their schedule puts them at the frame's time."""

    def __init__(self, mesh, scene):
        import numpy as np

        from ..model.surface import boundary_edges

        self.n = len(mesh.points)
        cells = {c.type: np.asarray(c.data, dtype=np.int64) for c in mesh.cells}
        self.triangles = cells.get("triangle", np.zeros((0, 3), np.int64)).reshape(-1, 3)
        segments = cells.get("line", np.zeros((0, 2), np.int64)).reshape(-1, 2)
        self.edges = np.concatenate([boundary_edges(self.triangles), segments])
        body = np.asarray(mesh.point_data.get("body_id", np.zeros(self.n)), dtype=np.int64)
        kinematic = np.asarray(mesh.point_data.get("kinematic", np.zeros(self.n))) != 0
        self.body = body.reshape(self.n, -1)[:, 0]
        kinematic = kinematic.reshape(self.n, -1)[:, 0]
        ids, inverse = np.unique(self.body, return_inverse=True)
        moving = np.bincount(inverse, weights=~kinematic, minlength=len(ids)) > 0
        self.obstacle_vertex = ~moving[inverse]
        self.self_collision = bool(scene.self_collision)
        simulated = np.zeros(self.n, dtype=bool)
        simulated[self.triangles.ravel()] = True
        self.plane_vertices = np.flatnonzero(simulated & ~kinematic)
        self.scene = scene
        # triangles of mass-spring bodies only draw them: nothing keeps them from turning
        springy = np.asarray(mesh.point_data.get("mass_spring", np.zeros(self.n))) != 0
        springy = springy.reshape(self.n, -1)[:, 0]
        self.elements = self.triangles[~springy[self.triangles].all(axis=1)]

    def _planes_at(self, time: float):
        import numpy as np

        from ..model.kinematics import moving_plane_origins

        planes = self.scene.planes
        origins = np.array([p.origin for p in planes], dtype=float)
        normals = np.array([p.normal for p in planes], dtype=float)
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        limits = np.array([p.limit if p.limit is not None else (np.nan,) * 3 for p in planes],
                          dtype=float)
        velocities = np.array([p.velocity for p in planes], dtype=float)
        dt = self.scene.dt
        moved = moving_plane_origins(origins, velocities, limits, dt, int(round(time / dt)))
        return (origins if moved is None else moved), normals

    def check(self, mesh, vtu, counts: dict, time: float = 0.0) -> list[str]:
        import numpy as np

        from .intersection import crossing_edges_2d, inverted_triangles

        x, problems = _frame_positions(mesh, vtu, self.n)
        if problems:
            return problems
        pairs = crossing_edges_2d(x, self.edges, None if self.self_collision else self.body)
        ends = self.edges[pairs]  # (k, 2, 2)
        between_obstacles = self.obstacle_vertex[ends].all(axis=(1, 2))
        _, problems = _tally(counts, between_obstacles,
                             len(inverted_triangles(x, self.elements)),
                             "crossing boundary-edge pairs", "triangles")
        if self.scene.planes and len(self.plane_vertices):
            origins, normals = self._planes_at(time)
            written = mesh.field_data.get("plane_origins")  # where the run had the lines
            if written is not None:
                origins = np.asarray(written, dtype=float).reshape(-1, 3)
            beyond = _on_or_beyond(x[self.plane_vertices], origins, normals)
            counts["below_plane"] += beyond
            if beyond:
                problems.append(f"{beyond} vertices on or beyond a line")
        return problems


def run_scene(folder: Path, scene=None):
    """The scene a run's frames are checked against: ``scene`` (a SceneSpec the user
    gave, which must be the run's: its scene.toml, where there is one, must say the
    same) or the run's own scene.toml. Without either the planes cannot be checked, and
    the check is refused rather than passed (exit status 2)."""
    from ..errors import IpcsimError
    from ..scene import load_scene

    scene_file = Path(folder) / "scene.toml"
    if scene is not None:
        if scene_file.exists() and load_scene(scene_file) != scene:
            raise IpcsimError(f"{scene.source} (with its --set values) is not the scene of "
                              f"the run in {folder} (its scene.toml differs); leave it out "
                              "to check the frames against the run's own scene")
        return scene
    if not scene_file.exists():
        raise IpcsimError(f"{scene_file}: not found; the frames cannot be checked against "
                          "the run's planes without the run's scene: give it, `ipcsim "
                          f"check SCENE --frames {folder}`")
    return load_scene(scene_file)  # refuses a folder or a special file in its place


def _scene_of_run(folder: Path, scene=None):
    """((origins, normals) of the run's planes or None, whether self collision is on),
    from :func:`run_scene`."""
    import numpy as np

    scene = run_scene(folder, scene)
    planes = None
    if scene.planes:
        planes = (np.array([p.origin for p in scene.planes], dtype=float),
                  np.array([p.normal for p in scene.planes], dtype=float))
    return planes, scene.self_collision
