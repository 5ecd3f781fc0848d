"""Regression comparison of two runs (or of a run and a golden reference, or of a run and
the original IPC program's output).

Positions: for every frame step compared, the largest and the RMS vertex distance
|x_A - x_B|, divided by the scene size (bounding-box diagonal of A's first frame). A
frame differs when some vertex moved more than ``atol + rtol * size``.
Logs: Newton iterations and contact counts of every step in ``steps.csv`` must be equal.

A is always a run folder. B is read into a :class:`Reference` (some frames' positions,
optionally of only some of A's vertices, and the logged counts), so one comparison serves
every kind of B:

* a run folder: every frame and every vertex; both runs must have the same frames;
* a golden reference (a ``.json`` file, see :func:`golden_from_run`): a few frames of a
  few sampled vertices and the per-step counts of a short run, a few KB kept in a
  repository (tests/regression/); its frames must be among A's;
* a folder of the original program's ``<n>.obj`` files (the surface after n steps: ``v``
  lines for the vertices used by some surface triangle, in increasing global vertex
  order); A's surface vertices (of boundary triangles of tets and of triangle cells) are
  compared by index, every frame of A must have its ``<n>.obj``, and there are no logs.

Verdict: 0 same within tolerance, 1 different, 2 cannot compare (raised as
:class:`CompareError`).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Callable
from functools import partial
from pathlib import Path

from msgspec import Struct, field
import numpy as np

from ..errors import IpcsimError, excerpt
from ..atomic import atomic_path, atomic_write_text
from .render import RenderError, load_run_frames
from .vtk import FrameError, read_frame

__all__ = ["COUNT_COLUMNS", "GOLDEN_FORMAT", "CompareError", "CompareResult", "Reference",
           "compare_runs", "golden_from_run", "mesh_signature", "plot_result",
           "read_golden", "read_obj_vertices", "read_reference", "write_golden"]

COUNT_COLUMNS = ("newton_iterations", "contacts_plane", "contacts_point_triangle",
                 "contacts_edge_edge", "contacts_total")
GOLDEN_FORMAT = "ipcsim-golden-1"
_OBJ_RE = re.compile(r"^(\d+)\.obj$")


class CompareError(IpcsimError):
    """The two folders cannot be compared (missing files or frames, other meshes)."""


class CompareResult(Struct):
    steps: list[int] = field(default_factory=list)  # compared frame steps
    times: list[float] = field(default_factory=list)
    max_rel: list[float] = field(default_factory=list)  # per frame, / scene size
    rms_rel: list[float] = field(default_factory=list)
    scale: float = 1.0
    tolerance: float = 0.0  # metres
    log_steps: list[int] = field(default_factory=list)
    counts_a: dict = field(default_factory=dict)  # column -> array over log_steps
    counts_b: dict = field(default_factory=dict)
    first_frame_diff: str | None = None
    first_frame_step: int | None = None
    first_count_diff: str | None = None
    first_count_step: int | None = None
    log_note: str | None = None  # why the logs were not compared
    original_format: bool = False

    @property
    def same(self) -> bool:
        return self.first_frame_diff is None and self.first_count_diff is None

    def first_difference(self) -> str | None:
        """The earliest difference (frame positions or a logged count)."""
        found = [(s, d) for s, d in ((self.first_frame_step, self.first_frame_diff),
                                     (self.first_count_step, self.first_count_diff))
                 if d is not None]
        return min(found)[1] if found else None


def read_obj_vertices(path) -> np.ndarray:
    """The ``v x y z`` lines of an OBJ file, (n, 3) float64."""
    rows = []
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            for k, line in enumerate(f, start=1):
                if line.startswith("v ") or line.startswith("v\t"):
                    parts = line.split()
                    if len(parts) < 4:
                        raise CompareError(f"{path}:{k}: a 'v' line needs x y z")
                    try:
                        rows.append([float(p) for p in parts[1:4]])
                    except ValueError:
                        raise CompareError(f"{path}:{k}: not a number in {line.strip()!r}")
    except OSError as exc:
        raise CompareError(f"{path}: cannot read ({exc})") from exc
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def _read_vtu(path):
    try:
        return read_frame(path)
    except FrameError as exc:  # a damaged input: cannot compare (not "different")
        raise CompareError(str(exc)) from None


def _cells(mesh) -> dict[str, np.ndarray]:
    out: dict[str, list] = {}
    for c in mesh.cells:
        out.setdefault(c.type, []).append(np.asarray(c.data, dtype=np.int64))
    return {k: np.concatenate(v) for k, v in out.items()}


def surface_vertices(mesh) -> np.ndarray:
    """Global indices of the vertices of A's surface triangles, increasing."""
    from ..model.surface import boundary_triangles

    cells = _cells(mesh)
    tris = [boundary_triangles(cells["tetra"])] if "tetra" in cells else []
    if "triangle" in cells:
        tris.append(cells["triangle"])
    if not tris:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate([t.ravel() for t in tris]))


def scene_size(points, where: str = "") -> float:
    """The bounding-box diagonal of the finite ``points`` (metres), the scale of every
    relative difference: 1 (absolute units) for a single point or none. Vertices with a
    NaN or infinite coordinate are left out, so that they make no tolerance NaN or
    infinite (and are themselves compared as infinitely far). A diagonal that overflows
    is a CompareError."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    finite = points[np.isfinite(points).all(axis=1)]
    if not len(finite):
        return 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        size = float(np.linalg.norm(finite.max(axis=0) - finite.min(axis=0)))
    if not math.isfinite(size):
        raise CompareError(f"{where}: the scene's size (its bounding-box diagonal) is beyond "
                           "the largest float: no relative tolerance can be taken")
    return size or 1.0


def _run_frames(folder: Path, which: str):
    try:
        return load_run_frames(folder)
    except RenderError as exc:
        raise CompareError(f"{which}: {exc}") from exc


def _original_frames(folder: Path) -> dict[int, Path]:
    return {int(m.group(1)): p for p in folder.iterdir()
            if (m := _OBJ_RE.match(p.name)) and p.is_file()}


def _names(steps) -> str:
    steps = sorted(steps)
    shown = ", ".join(f"frame_{s:06d}" for s in steps[:5])
    return shown + (f" and {len(steps) - 5} more" if len(steps) > 5 else "")


def _positions(path: Path) -> np.ndarray:
    return np.asarray(_read_vtu(path).points, dtype=np.float64)


def _adaptive(steps: list) -> bool:
    """Whether a steps.csv's step column has a row per attempted step (adaptive time
    steps: several rows for one step of dt)."""
    return len(set(steps)) < len(steps)


def _read_log(folder: Path, which: str) -> dict[str, np.ndarray]:
    """The step numbers and :data:`COUNT_COLUMNS` of ``folder/steps.csv``."""
    from .csv_log import read_csv

    p = folder / "steps.csv"
    if not p.is_file():
        raise CompareError(f"missing file: {which}'s {p}")
    try:
        log = read_csv(p)
    except (ValueError, OSError) as exc:
        raise CompareError(f"{which}: {p}: {exc}") from exc
    absent = [c for c in ("step", *COUNT_COLUMNS) if c not in log]
    if absent:
        raise CompareError(f"{which}'s steps.csv lacks the columns {', '.join(absent)}")
    return {c: log[c] for c in ("step", *COUNT_COLUMNS)}


def mesh_signature(mesh) -> dict:
    """Vertex count, cell counts and a SHA-256 of the connectivity (little-endian int64,
    cell types in name order): equal signatures mean the same mesh, in a few bytes that a
    golden reference can carry."""
    cells = _cells(mesh)
    digest = hashlib.sha256()
    for kind in sorted(cells):
        digest.update(kind.encode())
        digest.update(np.ascontiguousarray(cells[kind], dtype="<i8").tobytes())
    return {"vertices": len(mesh.points),
            "cells": {kind: len(cells[kind]) for kind in sorted(cells)},
            "sha256": digest.hexdigest()}


class Reference(Struct):
    """B as the comparison sees it, whatever it was read from: some frames' positions
    (optionally of only some of A's vertices) and the logged counts.

    ``kind`` says which frames are compared: a ``"run"`` must have exactly A's frames, a
    ``"golden"`` reference's few frames must be among A's, ``"original"`` output must have
    every frame of A (and holds A's surface vertices only, found from A's mesh)."""

    kind: str
    frames: dict[int, Callable[[], np.ndarray]]  # step -> reads that frame's positions
    names: dict[int, str]  # step -> B's frame as messages name it
    source: str = ""  # where B was read from, for messages
    index: np.ndarray | None = None  # A's vertices the positions are of; None: all
    mesh: dict | None = None  # the mesh_signature A must have; None: not checked
    log: dict[str, np.ndarray] | None = None  # step and COUNT_COLUMNS; None: no logs


def read_reference(b) -> Reference:
    """B for :func:`compare_runs`: a run folder, a folder of original ``<n>.obj`` files or
    a golden reference file."""
    b = Path(b)
    if b.is_file():
        return read_golden(b)
    if not b.is_dir():
        raise CompareError(f"B: {b}: no such folder")
    if (b / "frames").is_dir():
        run = _run_frames(b, "B")
        paths = dict(zip(run.steps, run.paths))
        return Reference("run", {s: partial(_positions, p) for s, p in paths.items()},
                         {s: p.name for s, p in paths.items()}, source=str(b),
                         mesh=mesh_signature(_read_vtu(run.paths[0])), log=_read_log(b, "B"))
    paths = _original_frames(b)
    if not paths:
        raise CompareError(f"B: {b} holds neither frames/frame_*.vtu nor original "
                           "<n>.obj files")
    return Reference("original", {s: partial(read_obj_vertices, p) for s, p in paths.items()},
                     {s: p.name for s, p in paths.items()}, source=str(b))


def _compared_steps(run_a, ref: Reference) -> list[int]:
    in_a, in_b = set(run_a.steps), set(ref.frames)
    if ref.kind == "golden":
        if in_b - in_a:
            raise CompareError(f"missing frames: {_names(in_b - in_a)} in the golden "
                               f"reference {ref.source} but not in A")
        return sorted(in_b)
    if ref.kind == "original":
        missing = in_a - in_b
        if missing:
            raise CompareError(f"missing frames: B ({ref.source}) has no <n>.obj for steps "
                               + ", ".join(str(s) for s in sorted(missing)[:10])
                               + (" ..." if len(missing) > 10 else ""))
        return list(run_a.steps)
    if in_a != in_b:
        msg = []
        if in_a - in_b:
            msg.append(f"{_names(in_a - in_b)} in A but not in B")
        if in_b - in_a:
            msg.append(f"{_names(in_b - in_a)} in B but not in A")
        raise CompareError("missing frames: " + "; ".join(msg))
    return list(run_a.steps)


def compare_runs(a, b, rtol: float = 1e-6, atol: float = 0.0) -> CompareResult:
    """Compare output folder ``a`` with ``b``: a run folder, a golden reference file,
    original ``<n>.obj`` files, or a :class:`Reference` already in memory."""
    if not (0 <= rtol < math.inf and 0 <= atol < math.inf):
        raise CompareError(f"tolerances must be finite and non-negative (rtol {rtol}, "
                           f"atol {atol})")
    a = Path(a)
    ref = b if isinstance(b, Reference) else read_reference(b)
    run_a = _run_frames(a, "A")
    steps = _compared_steps(run_a, ref)
    res = CompareResult()
    res.original_format = ref.kind == "original"

    first = _read_vtu(run_a.paths[0])
    n = len(first.points)
    res.scale = scene_size(first.points, f"A: {run_a.paths[0]}")
    res.tolerance = atol + rtol * res.scale
    if not math.isfinite(res.tolerance):
        raise CompareError(f"the tolerance {atol} + {rtol} x {res.scale:.3g} m is not finite")
    index = ref.index
    if ref.kind == "original":
        index = surface_vertices(first)
        if len(index) == 0:
            raise CompareError(f"A: {run_a.paths[0]} has no surface triangles to compare "
                               "with OBJ files")
    if ref.mesh is not None:
        mine = mesh_signature(first)
        if mine["vertices"] != ref.mesh.get("vertices"):
            raise CompareError(f"different vertex counts: A has {n}, B has "
                               f"{ref.mesh.get('vertices')} ({ref.names[min(ref.frames)]})")
        if mine != ref.mesh:
            raise CompareError("different meshes: A and B have the same vertex count but "
                               "different cells")

    frame_of = {s: k for k, s in enumerate(run_a.steps)}
    for step in steps:
        path_a, t = run_a.paths[frame_of[step]], run_a.times[frame_of[step]]
        xa = _positions(path_a)
        if len(xa) != n:
            raise CompareError(f"A: {path_a.name} has {len(xa)} vertices, "
                               f"{run_a.paths[0].name} has {n}")
        if index is not None:
            xa = xa[index]
        xb = ref.frames[step]()
        if len(xb) != len(xa):
            what = "" if index is None else " compared"
            raise CompareError(f"different vertex counts: A has {len(xa)}{what} vertices, "
                               f"B's {ref.names[step]} has {len(xb)}")
        d = np.linalg.norm(xa - xb, axis=1)
        d[~np.isfinite(d)] = np.inf  # NaN never counts as equal
        dmax = float(d.max()) if d.size else 0.0
        res.steps.append(step)
        res.times.append(t)
        res.max_rel.append(dmax / res.scale)
        res.rms_rel.append(float(np.sqrt(np.mean(d ** 2))) / res.scale if d.size else 0.0)
        if res.first_frame_diff is None and dmax > res.tolerance:
            name = path_a.name if ref.kind == "run" else f"{path_a.name} vs {ref.names[step]}"
            vertex = int(np.argmax(d)) if index is None else int(index[np.argmax(d)])
            res.first_frame_diff = (
                f"frame {name} (step {step}): largest vertex position difference "
                f"{dmax:.3g} m = {dmax / res.scale:.3g} of the scene size "
                f"(vertex {vertex}), tolerance {res.tolerance:.3g} m")
            res.first_frame_step = step

    if ref.log is not None:
        _compare_logs(res, _read_log(a, "A"), ref.log)
    return res


def _compare_logs(res: CompareResult, la: dict, lb: dict) -> None:
    """The Newton iterations and contact counts of A's and B's steps.csv, step by step
    (the first difference into ``res``)."""
    sa, sb = list(la["step"]), list(lb["step"])
    if sa != sb and (_adaptive(sa) or _adaptive(sb)):
        # a row per attempted step: runs with different steps compare by frames only
        res.log_note = (f"steps.csv not compared: A logs {len(sa)} attempted steps, "
                        f"B {len(sb)} (adaptive time steps)")
        return
    if sa != sb:
        raise CompareError(f"steps.csv: A logs {len(sa)} steps, B {len(sb)} "
                           "(different steps)")
    res.log_steps = sa
    for c in COUNT_COLUMNS:
        res.counts_a[c], res.counts_b[c] = la[c], lb[c]
    for k, step in enumerate(sa):
        diff = [c for c in COUNT_COLUMNS if la[c][k] != lb[c][k]]
        if diff:
            c = diff[0]
            res.first_count_diff = f"step {step}: {c} {la[c][k]} in A, {lb[c][k]} in B"
            res.first_count_step = int(step)
            return


# Golden references: a short run kept in a few KB. Positions are written with repr (17
# significant digits), so a reference compared with the run it was taken from differs by 0.

def golden_from_run(folder, frames: int = 4, vertices: int = 20, about=None) -> dict:
    """A golden reference of the run in ``folder``: ``frames`` frames spread evenly over
    the run (first and last included), the positions there of ``vertices`` vertices spread
    evenly over the numbering (so every body of a multi-body scene has some), and every
    step's Newton iterations and contact counts. ``about`` is kept as free information."""
    if vertices < 1 or frames < 1:
        raise ValueError(f"a golden reference needs at least one vertex and one frame "
                         f"(vertices={vertices}, frames={frames})")
    folder = Path(folder)
    run = _run_frames(folder, "run")
    first = _read_vtu(run.paths[0])
    n = len(first.points)
    index = np.unique(np.linspace(0, n - 1, min(vertices, n)).round().astype(np.int64))
    picks = np.unique(np.linspace(0, len(run.steps) - 1, min(frames, len(run.steps)))
                      .round().astype(np.int64))
    log = _read_log(folder, "run")
    return {
        "format": GOLDEN_FORMAT,
        "about": dict(about or {}),
        "mesh": mesh_signature(first),
        "vertices": index.tolist(),
        "frames": [{"step": run.steps[k], "time": run.times[k],
                    "positions": _positions(run.paths[k])[index].tolist()} for k in picks],
        "log": {c: log[c].tolist() for c in ("step", *COUNT_COLUMNS)},
    }


def write_golden(path, golden: dict) -> Path:
    """Write a golden reference as JSON with each list of numbers on one line (a vertex's
    position, a log column), so that a regenerated reference reads well in a diff."""
    text = json.dumps(golden, indent=1)
    text = re.sub(r"\[\s+([^\[\]{}\"]*?)\s+\]",
                  lambda m: "[" + " ".join(m.group(1).split()) + "]", text)
    return atomic_write_text(path, text + "\n", fsync=False)


def read_golden(path) -> Reference:
    """A golden reference file (:func:`write_golden`) as a :class:`Reference`."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise CompareError(f"{path}: cannot read as a golden reference ({exc})") from exc
    if not isinstance(data, dict) or data.get("format") != GOLDEN_FORMAT:
        raise CompareError(f"{path}: not a golden reference (no \"format\": "
                           f"\"{GOLDEN_FORMAT}\")")
    try:
        frames = {int(f["step"]): np.asarray(f["positions"], dtype=np.float64).reshape(-1, 3)
                  for f in data["frames"]}
        log = {c: np.asarray(data["log"][c]) for c in ("step", *COUNT_COLUMNS)}
        vertices = data["vertices"]
        if not isinstance(vertices, list) or not all(
                isinstance(v, int) and not isinstance(v, bool) for v in vertices):
            raise ValueError("\"vertices\" must list vertex numbers (whole numbers)")
        index = np.asarray(vertices, dtype=np.int64)
        mesh = dict(data["mesh"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CompareError(f"{path}: damaged golden reference ({exc!r})") from exc
    if index.ndim != 1 or len(index) == 0:
        raise CompareError(f"{path}: the golden reference samples no vertex (\"vertices\" "
                           "is empty): it would compare nothing")
    n = mesh.get("vertices")
    if isinstance(n, bool) or not isinstance(n, int) or index.min() < 0 or index.max() >= n:
        raise CompareError(f"{path}: damaged golden reference (its sampled vertices are not "
                           f"among the mesh's {excerpt(n)} vertices)")
    if len(frames) == 0 or any(len(x) != len(index) for x in frames.values()):
        raise CompareError(f"{path}: damaged golden reference (every frame needs one "
                           "position per sampled vertex)")
    return Reference("golden", {s: (lambda x=x: x) for s, x in frames.items()},
                     {s: path.name for s in frames}, source=str(path), index=index,
                     mesh=mesh, log=log)


def plot_result(res: CompareResult, path) -> Path:
    """Chart the position differences (and log counts) over the run, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    times = np.asarray(res.times, dtype=float)
    use_time = len(times) and np.isfinite(times).all()
    x = times if use_time else np.asarray(res.steps, dtype=float)
    n_ax = 2 if res.log_steps else 1
    fig, axes = plt.subplots(n_ax, 1, figsize=(8, 3.2 * n_ax), squeeze=False)
    ax = axes[0, 0]
    floor = 1e-17  # log axis: exact zeros drawn at the floor
    ax.semilogy(x, np.maximum(res.max_rel, floor), "o-", label="largest")
    ax.semilogy(x, np.maximum(res.rms_rel, floor), "s-", label="RMS")
    ax.axhline(max(res.tolerance / res.scale, floor), color="red", ls="--", label="tolerance")
    ax.set_xlabel("time (s)" if use_time else "step")
    ax.set_ylabel("|x_A - x_B| / scene size")
    ax.legend()
    ax.grid(True, alpha=0.3)
    if res.log_steps:
        ax = axes[1, 0]
        for c in ("newton_iterations", "contacts_total"):
            ax.plot(res.log_steps, np.asarray(res.counts_b[c]) - np.asarray(res.counts_a[c]),
                    ".-", label=f"{c} (B - A)")
        ax.set_xlabel("step")
        ax.set_ylabel("difference")
        ax.legend()
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fmt = path.suffix.lstrip(".").lower() or "png"
    try:
        with atomic_path(path, fsync=False) as tmp:
            fig.savefig(tmp, format=fmt, dpi=100)  # temp name has no suffix to infer from
    except OSError as exc:
        raise CompareError(f"--plot {path}: cannot write ({exc.strerror or exc})") from None
    except ValueError as exc:  # an image format matplotlib does not know
        raise CompareError(f"--plot {path}: {str(exc)[:120]}") from None
    finally:
        plt.close(fig)
    return path


def format_summary(res: CompareResult) -> str:
    lines = [f"compared {len(res.steps)} frames; scene size {res.scale:.4g} m, "
             f"tolerance {res.tolerance:.3g} m"]
    if res.steps:
        k = int(np.argmax(res.max_rel))
        lines.append(f"largest position difference {res.max_rel[k]:.3g} of the scene size "
                     f"(step {res.steps[k]}), largest RMS {max(res.rms_rel):.3g}")
    if res.log_steps:
        lines.append(f"compared Newton iterations and contact counts of {len(res.log_steps)} "
                     "steps")
    elif res.log_note:
        lines.append(res.log_note)
    elif res.original_format:
        lines.append("original-format B: surface vertices only, no logs compared")
    first = res.first_difference()
    lines.append("same within tolerance" if first is None else f"DIFFERENT: first at {first}")
    return "\n".join(lines)
