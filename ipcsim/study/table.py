"""study.csv (one row per run, a failed run a row with its error), the errors against
a reference run, and the chart of one column against one parameter."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from ..io.output_folder import STUDY_CHART as CHART_NAME
from ..io.output_folder import STUDY_COLUMNS as _FIRST
from ..io.output_folder import STUDY_TABLE as TABLE_NAME

__all__ = ["write_table", "read_table", "reference_errors", "chart", "TABLE_NAME",
           "CHART_NAME"]
_LAST = ("folder", "action", "inputs_sha256")


def columns_of(rows: list[dict], keys) -> list[str]:
    """run, status, error, the parameters, then every other column in the order met."""
    seen = list(dict.fromkeys(k for r in rows for k in r))
    middle = [k for k in seen if k not in (*_FIRST, *keys, *_LAST)]
    return [*_FIRST, *keys, *middle, *[k for k in _LAST if k in seen]]


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def write_table(path: Path, rows: list[dict], keys) -> Path:
    """Write study.csv atomically (a study stopped at any moment keeps a whole table)."""
    from ..atomic import atomic_write_text

    cols = columns_of(rows, keys)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        w.writerow([_cell(r.get(c)) for c in cols])
    atomic_write_text(path, buf.getvalue())
    return path


def read_table(path: Path) -> list[dict]:
    """study.csv's rows, numbers as numbers."""
    def value(text: str):
        for kind in (int, float):
            try:
                return kind(text)
            except ValueError:
                pass
        return {"True": True, "False": False}.get(text, text)

    with open(path, newline="") as f:
        return [{k: value(v) for k, v in row.items()} for row in csv.DictReader(f)]


def _frames(folder: Path) -> dict[float, Path]:
    from ..io.vtk import SERIES_NAME, read_series

    return {round(t, 9): p for t, p in read_series(Path(folder) / "frames" / SERIES_NAME)}


def reference_errors(rows: list[dict], reference: dict) -> None:
    """Add ``error_rms`` and ``error_max`` to each finished row: vertex positions against
    the reference run's at the frame times both have, over the reference's bounding-box
    diagonal l (RMS over times and vertices; largest vertex distance). Runs with another
    vertex count (another mesh) get no error."""
    import numpy as np

    from ..io.vtk import read_frame

    ref = _frames(reference["folder"])
    if not ref:
        return
    from ..io.compare import CompareError, scene_size

    try:  # compare's scale: NaN coordinates never make every error NaN
        diagonal = scene_size(read_frame(ref[min(ref)]).points)
    except CompareError:
        return
    cache: dict = {}
    for row in rows:
        if row.get("status") != "ok":
            continue
        mine = _frames(row["folder"])
        common = sorted(set(mine) & set(ref))
        sq, worst, count = 0.0, 0.0, 0
        for t in common:
            x = read_frame(mine[t]).points
            if t not in cache:
                cache[t] = read_frame(ref[t]).points
            if x.shape != cache[t].shape:
                common = []
                break
            d2 = np.sum((x - cache[t]) ** 2, axis=1)
            sq, worst, count = sq + float(d2.sum()), max(worst, float(d2.max())), count + len(d2)
        row["error_rms"] = math.sqrt(sq / count) / diagonal if common else math.nan
        row["error_max"] = math.sqrt(worst) / diagonal if common else math.nan
        row["error_frames"] = len(common)


def _log_scale(values) -> bool:
    return all(v > 0 for v in values) and max(values) >= 10 * min(values)


def chart(path: Path, rows: list[dict], x: str, y: str, keys, *, log_x=None,
          log_y=False, title="") -> Path | None:
    """``y`` against ``x`` over the finished runs, one line per combination of the other
    parameters; None when no run has both as numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    pts = [r for r in rows if r.get("status") == "ok" and number(r.get(x))
           and number(r.get(y))]
    if not pts:
        return None
    others = [k for k in keys if k != x]
    groups: dict[tuple, list] = {}
    for r in pts:
        groups.setdefault(tuple(r.get(k) for k in others), []).append(r)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for label, sel in groups.items():
        sel = sorted(sel, key=lambda r: r[x])
        name = ", ".join(f"{k} = {v:g}" if number(v) else f"{k} = {v}"
                         for k, v in zip(others, label)) or None
        ax.plot([r[x] for r in sel], [r[y] for r in sel], "o-", label=name)
    if log_x if log_x is not None else _log_scale([r[x] for r in pts]):
        ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    if others:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
