"""Mesh readers: plain numpy arrays in, every failure a ``MeshError`` naming the file.

Formats (docs/ipc-scene-format.md §6):

* tet meshes: Gmsh ``.msh`` 4.1 ASCII (own reader, ``gmsh.py``) and 2.2 or binary (meshio,
  ``file_format="gmsh"``; the original's trailing ``$Surface`` block is ignored and the
  boundary recomputed), ``.vtk`` / ``.vtu`` (meshio), TetGen ``.node`` + ``.ele`` (own
  reader);
* ``.obj`` triangle surfaces (own parser of ``v`` and ``f`` lines; meshio for a file it
  cannot read);
* ``.seg`` segments (``v x y z`` / ``s i j``, 1-based; missing file -> unique edges of the
  ``.obj`` of the same stem) and ``.pt`` points (``v`` lines; missing -> the ``.obj``'s
  vertices);
* the original's ``status<n>`` restart files;
* 2D scenes: triangle meshes in the plane z = 0 (``.msh`` with 3-node triangles, ``.obj``),
  and ``.seg`` / ``.pt`` files in that plane (``read_shape_2d``).

Every reader takes ``(path, line)``: ``line`` is the scene line that asked for the file and
is carried into the ``MeshError`` so a user sees which shape failed.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np

from ..errors import MeshError, excerpt, one_line
from .gmsh import GmshText
from .gmsh import parse as parse_gmsh
from .mesh_check import (
    check_gmsh_tags,
    check_indices,
    check_planar,
    check_points,
    check_segments,
    check_tet_mesh,
    check_triangle_mesh,
    check_triangles,
)
from .surface import unique_edges, unique_undirected

__all__ = ["check_triangles", "read_frame_positions", "read_obj", "read_pt", "read_seg",
           "read_shape", "read_shape_2d", "read_status", "read_tet_mesh", "read_tetgen",
           "read_triangle_mesh"]

# `v x y z` and `s i j` records of OBJ-like text files (one match per line, in C via re)
_V_RE = re.compile(r"^[ \t]*v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", re.M)
_S_RE = re.compile(r"^[ \t]*s[ \t]+(\S+)[ \t]+(\S+)", re.M)
_F_RE = re.compile(r"^[ \t]*f[ \t]+([^\n#]*)", re.M)
_RELATIVE_FACE_RE = re.compile(r"^[ \t]*f[ \t][^\n#]*?(?<!\S)-\d", re.M)


def _err(path, line, message: str) -> MeshError:
    return MeshError(path, line, message)


def _read_text(path: Path, line) -> str:
    try:
        return Path(path).read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise _err(path, line, "mesh file not found") from None
    except OSError as exc:
        raise _err(path, line, f"cannot read mesh file ({exc.strerror or exc})") from None


def _meshio_read(path: Path, line, file_format: str):
    """Read with meshio's per-format reader; every exception (and chatter) contained.

    The per-format readers raise instead of printing and calling ``sys.exit`` as
    ``meshio.read`` does on a ReadError.
    """
    import meshio

    if not Path(path).is_file():
        raise _err(path, line, "is not a regular file" if Path(path).exists()
                   else "mesh file not found")
    readers = {"gmsh": meshio.gmsh.read, "vtk": meshio.vtk.read, "vtu": meshio.vtu.read,
               "obj": meshio.obj.read}
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return readers[file_format](str(path))
    except (Exception, SystemExit) as exc:  # ReadError, ValueError, IndexError, ...
        msg = one_line(str(exc).strip() or type(exc).__name__, 160)
        raise _err(path, line, f"cannot read mesh ({msg})") from None


def _to_float_array(tokens, path, line, what: str) -> np.ndarray:
    try:
        return np.asarray(tokens, dtype=np.float64)
    except ValueError:
        raise _err(path, line, f"non-numeric {what}") from None


def _to_int_array(tokens, path, line, what: str) -> np.ndarray:
    try:
        arr = np.asarray(tokens, dtype=np.float64)
    except ValueError:
        raise _err(path, line, f"non-numeric {what}") from None
    if arr.size and (not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr))):
        raise _err(path, line, f"non-integer {what}")
    return arr.astype(np.int64)


def _drop_unreferenced(points: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Remove vertices no cell uses (e.g. Gmsh geometry points) and renumber the cells."""
    used = np.zeros(len(points), dtype=bool)
    used[cells.ravel()] = True
    if used.all():
        return points, cells
    new_index = np.cumsum(used) - 1  # old index -> new index for used vertices
    return points[used], new_index[cells]


# ----------------------------------------------------------------------------- tet meshes


def read_tet_mesh(path, line: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a tetrahedral mesh: (points (n, 3) float64, tets (m, 4) int64, 0-based).

    Vertices used by no tet are dropped (and the tets renumbered). Raises MeshError for an
    unreadable file, a file without linear tets, and everything ``mesh_check`` refuses:
    NaN/inf or huge coordinates, indices (Gmsh node tags) that name no vertex, zero-volume,
    inverted or duplicate tets, overlapping tets, no closed boundary.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".ele" or suffix == "" or suffix == ".node":
        points, tets = read_tetgen(path, line)
    else:
        fmt = {".msh": "gmsh", ".vtk": "vtk", ".vtu": "vtu"}.get(suffix)
        if fmt is None:
            raise _err(path, line, f"unsupported tet mesh format '{suffix}' "
                                   "(use .msh, .vtk, .vtu or TetGen .node/.ele)")
        parsed = _gmsh_text(path) if fmt == "gmsh" else None
        if parsed is not None:  # ASCII Gmsh: its tags checked before meshio maps a bad
            check_gmsh_tags(path, line, parsed)  # tag onto another node
        own = parsed.tetrahedra() if parsed is not None else None
        if own is not None:  # MSH 4.1 ASCII, the original's meshes: no meshio import
            points, tets = own
            return _checked_tet_mesh(check_points(points, path, line),
                                     check_indices(tets, len(points), path, line, "tet"),
                                     path, line)
        mesh = _meshio_read(path, line, fmt)
        blocks = [c.data for c in mesh.cells if c.type == "tetra"]
        if not blocks:
            kinds = sorted({c.type for c in mesh.cells})
            hint = ""
            if "triangle" in kinds:
                hint = " (a triangle surface is not a solid: tetrahedralize it, or use an .obj "\
                       "shape for a kinematic surface)"
            if "tetra10" in kinds:
                hint = " (only linear 4-node tetrahedra are supported)"
            raise _err(path, line, f"no tetrahedra in mesh (cells: {', '.join(kinds) or 'none'})"
                                   f"{hint}")
        points = check_points(mesh.points, path, line)
        tets = check_indices(np.concatenate(blocks).astype(np.int64), len(points), path, line,
                             "tet")
    return _checked_tet_mesh(points, tets, path, line)


def _checked_tet_mesh(points, tets, path, line) -> tuple[np.ndarray, np.ndarray]:
    points, tets = _drop_unreferenced(points, tets)
    check_tet_mesh(points, tets, path, line)
    return points, np.ascontiguousarray(tets, dtype=np.int64)


def _gmsh_text(path: Path) -> GmshText | None:
    """The file as an ASCII Gmsh file (``gmsh.parse``); None when it cannot be read here."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None  # meshio's reader reports why
    return parse_gmsh(text)


def _tokens(path: Path, line) -> np.ndarray:
    """All whitespace-separated tokens of a text file, ``#`` comments removed."""
    text = re.sub(r"#[^\n]*", "", _read_text(path, line))
    return np.array(text.split(), dtype=object)


def read_tetgen(path, line: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """TetGen ``<base>.node`` + ``<base>.ele`` (shape path ``<base>.ele`` or ``<base>``).

    ``.node``: header ``N 3 attrs markers`` then N rows ``id x y z [attrs] [marker]``;
    ``.ele``: header ``M 4 attrs`` then M rows ``id a b c d [attrs]``. Rows have a fixed
    width given by the header, so both files are parsed as one token array. Element
    indices refer to node ids; the numbering base (0 or 1) is taken from the first node id
    (the original uses the indices as-is, i.e. requires 0-based files; both agree there).
    """
    path = Path(path)
    base = path.with_suffix("") if path.suffix.lower() in (".ele", ".node") else path
    node_path, ele_path = base.with_name(base.name + ".node"), base.with_name(base.name + ".ele")

    tok = _tokens(node_path, line)
    try:
        n, dim, n_attr, n_mark = (int(t) for t in tok[:4])
        if min(n, n_attr, n_mark) < 0:
            raise ValueError
    except ValueError:
        raise _err(node_path, line, "bad .node header (expected 'N 3 attrs markers')") from None
    if dim != 3:
        raise _err(node_path, line, f".node dimension is {dim}, expected 3")
    width = 4 + n_attr + (1 if n_mark else 0)  # id x y z attrs [marker]
    if len(tok) < 4 + n * width:
        raise _err(node_path, line, f"truncated .node file (expected {n} vertices)")
    table = _to_float_array(tok[4:4 + n * width].reshape(n, width)[:, :4].astype(str),
                            node_path, line, "vertex record")
    first_id = int(table[0, 0]) if n else 0
    points = check_points(table[:, 1:4], node_path, line)

    tok = _tokens(ele_path, line)
    try:
        m, per, n_attr = (int(t) for t in tok[:3])
        if min(m, n_attr) < 0:
            raise ValueError
    except ValueError:
        raise _err(ele_path, line, "bad .ele header (expected 'M 4 attrs')") from None
    if per != 4:
        raise _err(ele_path, line, f"{per}-node elements; only linear 4-node tets are supported")
    width = 1 + per + n_attr  # id a b c d attrs
    if len(tok) < 3 + m * width:
        raise _err(ele_path, line, f"truncated .ele file (expected {m} tetrahedra)")
    rows = tok[3:3 + m * width].reshape(m, width)[:, 1:5].astype(str)
    tets = _to_int_array(rows, ele_path, line, "tet record") - first_id
    tets = check_indices(tets, len(points), ele_path, line, "tet")
    return points, tets


# ----------------------------------------------------------------------------- surfaces


def _parse_obj(text: str, path: Path, line) -> tuple[np.ndarray, np.ndarray]:
    """OBJ ``v`` and ``f`` lines (``a/b/c`` keeps ``a``; relative indices: ``f -3 -2 -1``
    names the last three vertices defined *before* that line, which meshio misreads).
    Non-triangle faces raise MeshError."""
    verts = _to_float_array(_V_RE.findall(text), path, line, "vertex coordinate").reshape(-1, 3)
    faces, defined = [], []
    count, last = 0, 0
    for m in _F_RE.finditer(text):
        count += len(_V_RE.findall(text, last, m.start()))  # vertices defined so far
        last = m.start()
        faces.append(re.sub(r"/\S*", "", m.group(1)).split())  # drop /vt/vn
        defined.append(count)
    sizes = np.fromiter(map(len, faces), dtype=np.int64, count=len(faces))
    if np.any(sizes != 3):
        raise _err(path, line, f"{int((sizes != 3).sum())} faces are not triangles "
                               "(only triangle meshes are supported)")
    raw = _to_int_array(faces, path, line, "face index").reshape(-1, 3)
    if np.any(raw == 0):
        raise _err(path, line, "face index 0: OBJ indices start at 1 (or count back from -1)")
    before = np.asarray(defined, dtype=np.int64)[:, None]
    return verts, np.where(raw < 0, before + raw, raw - 1)  # 1-based; negative: relative


def read_obj(path, line: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Triangle surface: (points (n, 3), triangles (k, 3) int64, 0-based).

    Faces that are not triangles are a MeshError (as in the original, which reads OBJs
    with libigl and exits on mixed polygon sizes)."""
    path = Path(path)
    text = _read_text(path, line)
    try:
        # the own parser first: meshio's import is 30–40 ms of a small scene's start, and
        # both give the same arrays, bit for bit, on every OBJ of the original's examples
        points, triangles = _parse_obj(text, path, line)
    except MeshError as own_error:
        if _RELATIVE_FACE_RE.search(text):  # meshio does not know relative indices
            raise
        try:
            mesh = _meshio_read(path, line, "obj")
        except MeshError:
            raise own_error from None
        other = sorted({c.type for c in mesh.cells} - {"triangle"})
        if other:
            raise _err(path, line, f"faces that are not triangles ({', '.join(other)}); "
                                   "only triangle meshes are supported") from None
        points = np.asarray(mesh.points, dtype=np.float64)
        tris = [c.data for c in mesh.cells]
        triangles = (np.concatenate(tris).astype(np.int64) if tris
                     else np.zeros((0, 3), np.int64))
    points = check_points(points, path, line)
    triangles = check_indices(triangles.reshape(-1, 3), len(points), path, line, "triangle")
    return points, triangles


def read_seg(path, line: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Segments: (points (n, 3), edges (e, 2) int64, 0-based).

    ``<stem>.seg`` holds ``v x y z`` and ``s i j`` (1-based) lines; other lines are ignored.
    If it does not exist, ``<stem>.obj`` is read and its unique undirected triangle edges
    are used (as the original does; the tutorials rely on it). A path that already names
    the ``.obj`` is read that way directly.
    """
    path = Path(path)
    if path.suffix.lower() == ".obj":  # the scene reader already resolved the fallback
        points, triangles = read_obj(path, line)
        return points, unique_edges(triangles)
    if not path.is_file():
        obj = path.with_suffix(".obj")
        if not obj.is_file():
            raise _err(path, line, f"mesh file not found (nor the fallback {obj.name})")
        points, triangles = read_obj(obj, line)
        return points, unique_edges(triangles)
    text = _read_text(path, line)
    points = check_points(
        _to_float_array(_V_RE.findall(text), path, line, "vertex coordinate").reshape(-1, 3),
        path, line)
    edges = _to_int_array(_S_RE.findall(text), path, line, "segment index").reshape(-1, 2) - 1
    edges = check_indices(edges, len(points), path, line, "segment")
    if len(points) == 0:
        raise _err(path, line, "no vertices in segment mesh")
    check_segments(edges, path, line)
    return points, edges


def read_pt(path, line: int | None = None) -> np.ndarray:
    """Point cloud (n, 3): the ``v`` lines of ``<stem>.pt`` (parsed as OBJ, faces ignored),
    or the vertices of ``<stem>.obj`` when the ``.pt`` file does not exist."""
    path = Path(path)
    if not path.is_file():
        obj = path.with_suffix(".obj")
        if not obj.is_file():
            raise _err(path, line, f"mesh file not found (nor the fallback {obj.name})")
        path = obj
    text = _read_text(path, line)
    points = _to_float_array(_V_RE.findall(text), path, line, "vertex coordinate").reshape(-1, 3)
    if len(points) == 0:
        raise _err(path, line, "no vertices ('v x y z' lines) in point file")
    return check_points(points, path, line)


# ----------------------------------------------------------------------------- one shape


def read_shape(path, kind: str, line: int | None = None) -> dict[str, np.ndarray]:
    """Load one scene shape in file coordinates by kind ('tet', 'surface', 'segments',
    'points'): a dict with ``points`` and, as they apply, ``tets``, ``triangles``, ``edges``.
    """
    if kind == "tet":
        points, tets = read_tet_mesh(path, line)
        return {"points": points, "tets": tets}
    if kind == "surface":
        points, triangles = read_obj(path, line)
        check_triangles(points, triangles, path, line)
        return {"points": points, "triangles": triangles}
    if kind == "segments":
        points, edges = read_seg(path, line)
        return {"points": points, "edges": unique_undirected(edges)}
    if kind == "points":
        return {"points": read_pt(path, line)}
    raise _err(path, line, f"unsupported mesh kind {kind!r}")


def read_triangle_mesh(path, line: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A 2D body: (points (n, 3) with z = 0, triangles (m, 3) int64 counter-clockwise),
    from an ``.msh`` (MSH 4.1 ASCII by ``gmsh.py``, else meshio's 3-node triangles) or an
    ``.obj``. Vertices used by no triangle are dropped; ``mesh_check`` refuses the rest."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        points, triangles = read_obj(path, line)
    else:
        parsed = _gmsh_text(path)
        if parsed is not None:
            check_gmsh_tags(path, line, parsed)
        own = parsed.triangles() if parsed is not None else None
        if own is not None:
            points, triangles = check_points(own[0], path, line), own[1]
        else:
            mesh = _meshio_read(path, line, "gmsh")
            blocks = [c.data for c in mesh.cells if c.type == "triangle"]
            if not blocks:
                kinds = sorted({c.type for c in mesh.cells})
                raise _err(path, line, "no triangles in mesh (cells: "
                                       f"{', '.join(kinds) or 'none'}); a 2D scene's bodies "
                                       "are 3-node triangles")
            points = check_points(mesh.points, path, line)
            triangles = np.concatenate(blocks).astype(np.int64)
    triangles = check_indices(triangles, len(points), path, line, "triangle")
    points, triangles = _drop_unreferenced(points, triangles)
    check_planar(points, path, line)
    return points, check_triangle_mesh(points, triangles, path, line)


def read_shape_2d(path, kind: str, line: int | None = None) -> dict[str, np.ndarray]:
    """``read_shape`` for a 2D scene: kind 'triangles', 'segments' or 'points', every
    vertex in the plane z = 0."""
    if kind == "triangles":
        points, triangles = read_triangle_mesh(path, line)
        return {"points": points, "triangles": triangles}
    if kind not in ("segments", "points"):
        raise _err(path, line, f"unsupported mesh kind {kind!r} in a 2D scene")
    data = read_shape(path, kind, line)
    check_planar(data["points"], path, line)
    return data


def read_frame_positions(path, ext: str, line: int | None = None) -> np.ndarray:
    """Vertex positions (n, 3) of one mesh-sequence frame ``<folder>/<k>.<ext>``.

    ext 'msh' (tet shape), 'obj', 'seg' (falls back to ``<k>.obj``), 'pt' (falls back to
    ``<k>.obj``). Positions are world coordinates.
    """
    path = Path(path)
    if ext == "msh":
        return read_tet_mesh(path, line)[0]
    if ext == "obj":
        return read_obj(path, line)[0]
    if ext == "seg":
        return read_seg(path, line)[0]
    if ext == "pt":
        return read_pt(path, line)
    raise _err(path, line, f"unsupported mesh-sequence extension {ext!r}")


# ----------------------------------------------------------------------------- restart


def read_status(path, line: int | None = None) -> tuple[int, np.ndarray, np.ndarray]:
    """The original's restart file ``status<n>``: (step n, positions (nV, 3),
    velocities (nV, 3)).

    Layout: ``timestep n``, ``position nV 3`` + nV rows, ``velocity 3nV`` + 3nV values
    (x0 y0 z0 x1 ...), then acceleration and dx_Elastic blocks (ignored here).
    """
    tokens = _read_text(Path(path), line).split()

    def find(word: str) -> int:
        try:
            return tokens.index(word)
        except ValueError:
            raise _err(path, line, f"restart file has no '{word}' block") from None

    try:
        written = float(tokens[find("timestep") + 1])
        if not (0 <= written <= 10**8 and written == int(written)):  # also inf and nan
            raise _err(path, line, f"restart file timestep {excerpt(tokens[find('timestep') + 1])}"
                                   " is not a step number (a whole number 0..1e8)")
        step = int(written)
        i = find("position")
        n_v, dim = int(tokens[i + 1]), int(tokens[i + 2])
        if dim != 3 or n_v < 0:
            raise ValueError
        positions = np.asarray(tokens[i + 3:i + 3 + 3 * n_v], dtype=np.float64)
        j = find("velocity")
        n_vel = int(tokens[j + 1])
        velocities = np.asarray(tokens[j + 2:j + 2 + n_vel], dtype=np.float64)
    except (ValueError, IndexError):
        raise _err(path, line, "malformed restart (status) file") from None
    if positions.size != 3 * n_v or n_vel != 3 * n_v or velocities.size != n_vel:
        raise _err(path, line, "truncated restart (status) file")
    positions = check_points(positions.reshape(n_v, 3), path, line)
    velocities = check_points(velocities.reshape(n_v, 3), path, line, bound=None,
                              what="velocities")
    return step, positions, velocities
