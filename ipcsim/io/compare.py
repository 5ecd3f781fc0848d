"""Regression comparison of two runs (or of a run and the original IPC program's output).

Positions: for every frame step present in both, the largest and the RMS vertex distance
|x_A - x_B|, divided by the scene size (bounding-box diagonal of A's first frame). A
frame differs when some vertex moved more than ``atol + rtol * size``.
Logs: Newton iterations and contact counts of every step in ``steps.csv`` must be equal.

B may be a folder of the original program's ``<n>.obj`` files (the surface after n
steps: ``v`` lines for the vertices used by some surface triangle, in increasing global
vertex order); A's surface vertices (of boundary triangles of tets and of triangle cells)
are then compared by index, and there are no logs to compare.

Verdict: 0 same within tolerance, 1 different, 2 cannot compare (raised as
:class:`CompareError`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import IpcsimError
from .atomic import atomic_path
from .render import load_run_frames, RenderError

__all__ = ["COUNT_COLUMNS", "CompareError", "CompareResult", "compare_runs", "plot_result",
           "read_obj_vertices"]

COUNT_COLUMNS = ("newton_iterations", "contacts_plane", "contacts_point_triangle",
                 "contacts_edge_edge", "contacts_total")
_OBJ_RE = re.compile(r"^(\d+)\.obj$")


class CompareError(IpcsimError):
    """The two folders cannot be compared (missing files or frames, other meshes)."""


@dataclass
class CompareResult:
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
    import meshio

    try:
        return meshio.read(path)
    except Exception as exc:  # meshio raises many kinds for a damaged file
        raise CompareError(f"{path}: cannot read frame ({exc})") from exc


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


def compare_runs(a, b, rtol: float = 1e-6, atol: float = 0.0) -> CompareResult:
    """Compare output folder ``a`` with ``b`` (a run or original ``<n>.obj`` files)."""
    from .csv_log import read_csv

    if not (rtol >= 0 and atol >= 0):
        raise CompareError(f"tolerances must be non-negative (rtol {rtol}, atol {atol})")
    a, b = Path(a), Path(b)
    if not b.is_dir():
        raise CompareError(f"B: {b}: no such folder")
    run_a = _run_frames(a, "A")
    res = CompareResult()
    if (b / "frames").is_dir():
        run_b = _run_frames(b, "B")
        only_a = set(run_a.steps) - set(run_b.steps)
        only_b = set(run_b.steps) - set(run_a.steps)
        if only_a or only_b:
            msg = []
            if only_a:
                msg.append(f"{_names(only_a)} in A but not in B")
            if only_b:
                msg.append(f"{_names(only_b)} in B but not in A")
            raise CompareError("missing frames: " + "; ".join(msg))
        paths_b = dict(zip(run_b.steps, run_b.paths))
        original = False
    else:
        paths_b = _original_frames(b)
        if not paths_b:
            raise CompareError(f"B: {b} holds neither frames/frame_*.vtu nor original "
                               "<n>.obj files")
        missing = set(run_a.steps) - set(paths_b)
        if missing:
            raise CompareError(f"missing frames: B ({b}) has no <n>.obj for steps "
                               + ", ".join(str(s) for s in sorted(missing)[:10])
                               + (" ..." if len(missing) > 10 else ""))
        original = True
    res.original_format = original

    first = _read_vtu(run_a.paths[0])
    n = len(first.points)
    lo, hi = first.points.min(axis=0), first.points.max(axis=0)
    res.scale = float(np.linalg.norm(hi - lo)) or 1.0  # a single point: absolute units
    res.tolerance = atol + rtol * res.scale
    if original:
        index = surface_vertices(first)
        if len(index) == 0:
            raise CompareError(f"A: {run_a.paths[0]} has no surface triangles to compare "
                               "with OBJ files")
    else:
        cells_a = _cells(first)
        fb = _read_vtu(paths_b[run_a.steps[0]])
        if len(fb.points) != n:
            raise CompareError(f"different vertex counts: A has {n}, B has "
                               f"{len(fb.points)} ({paths_b[run_a.steps[0]].name})")
        cells_b = _cells(fb)
        if cells_a.keys() != cells_b.keys() or any(
                not np.array_equal(cells_a[k], cells_b[k]) for k in cells_a):
            raise CompareError("different meshes: A and B have the same vertex count but "
                               "different cells")

    for step, path_a, t in zip(run_a.steps, run_a.paths, run_a.times):
        xa = np.asarray(_read_vtu(path_a).points, dtype=np.float64)
        if len(xa) != n:
            raise CompareError(f"A: {path_a.name} has {len(xa)} vertices, "
                               f"{run_a.paths[0].name} has {n}")
        if original:
            xb = read_obj_vertices(paths_b[step])
            xa = xa[index]
            if len(xb) != len(xa):
                raise CompareError(f"different vertex counts: A has {len(xa)} surface "
                                   f"vertices, {paths_b[step]} has {len(xb)} 'v' lines")
        else:
            xb = np.asarray(_read_vtu(paths_b[step]).points, dtype=np.float64)
            if len(xb) != n:
                raise CompareError(f"different vertex counts: A has {n}, B's "
                                   f"{paths_b[step].name} has {len(xb)}")
        d = np.linalg.norm(xa - xb, axis=1)
        d[~np.isfinite(d)] = np.inf  # NaN never counts as equal
        dmax = float(d.max()) if d.size else 0.0
        res.steps.append(step)
        res.times.append(t)
        res.max_rel.append(dmax / res.scale)
        res.rms_rel.append(float(np.sqrt(np.mean(d ** 2))) / res.scale if d.size else 0.0)
        if res.first_frame_diff is None and dmax > res.tolerance:
            name = path_a.name if not original else f"{path_a.name} vs {step}.obj"
            res.first_frame_diff = (
                f"frame {name} (step {step}): largest vertex position difference "
                f"{dmax:.3g} m = {dmax / res.scale:.3g} of the scene size "
                f"(vertex {int(np.argmax(d))}), tolerance {res.tolerance:.3g} m")
            res.first_frame_step = step

    if not original:
        logs = []
        for name, folder in (("A", a), ("B", b)):
            p = folder / "steps.csv"
            if not p.is_file():
                raise CompareError(f"missing file: {name}'s {p}")
            try:
                logs.append(read_csv(p))
            except (ValueError, OSError) as exc:
                raise CompareError(f"{name}: {p}: {exc}") from exc
        la, lb = logs
        for name, log in (("A", la), ("B", lb)):
            absent = [c for c in ("step", *COUNT_COLUMNS) if c not in log]
            if absent:
                raise CompareError(f"{name}'s steps.csv lacks the columns {', '.join(absent)}")
        sa, sb = list(la["step"]), list(lb["step"])
        if sa != sb:
            raise CompareError(f"steps.csv: A logs {len(sa)} steps, B {len(sb)} "
                               "(different steps)")
        res.log_steps = sa
        for c in COUNT_COLUMNS:
            res.counts_a[c], res.counts_b[c] = la[c], lb[c]
        for k, s in enumerate(sa):
            diff = [c for c in COUNT_COLUMNS if la[c][k] != lb[c][k]]
            if diff:
                c = diff[0]
                res.first_count_diff = (f"step {s}: {c} {la[c][k]} in A, {lb[c][k]} in B")
                res.first_count_step = int(s)
                break
    return res


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
    with atomic_path(path, fsync=False) as tmp:
        fig.savefig(tmp, format=fmt, dpi=100)  # temp name has no suffix to infer from
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
    elif res.original_format:
        lines.append("original-format B: surface vertices only, no logs compared")
    first = res.first_difference()
    lines.append("same within tolerance" if first is None else f"DIFFERENT: first at {first}")
    return "\n".join(lines)
