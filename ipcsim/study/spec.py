"""The study file: a base scene, the parameters to vary, what to record, an optional
reference run and a chart (docs/user-guide.md, "Studies").

::

    [study]
    scene = "drop.toml"               # the base scene, relative to this file
    output = "output/drop_study"      # optional (default output/<study-file-stem>)
    steps = 40                        # optional: stop every run after this step
    set = { "time.duration" = 0.4 }   # optional: overrides of every run

    [[vary]]                          # an axis: its keys change together (a zip)
    "time.dt" = [0.02, 0.01, 0.005]

    [[vary]]                          # axes combine as a product
    "contact.dhat" = { start = 1e-3, stop = 1e-2, num = 3, spacing = "log" }

    [record]
    columns = ["newton_iterations", "min_distance"]   # steps.csv columns
    summaries = ["min", "max", "mean", "final"]       # (the default)
    check_frames = true               # the exact checker over every frame
    final_state = true                # (the default)

    [reference]                       # optional: errors against this run
    set = { "time.dt" = 0.001 }

    [chart]
    x = "time.dt"
    y = "newton_iterations"           # any study.csv column
    log_x = true

A range is ``{start, stop, num}`` (``num`` points from start to stop, both included;
``spacing = "log"`` for a geometric series) or ``{start, stop, step}`` (start, start +
step, ... up to stop). Every mistake is a ``SceneError`` naming the study file, the line
and the key.
"""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path

from msgspec import Struct, field

from ..errors import SceneError, excerpt
from ..scene.toml_reader import KeyedReader, locate_keys
from ..scene.txt_reader import suggest

__all__ = ["StudySpec", "Axis", "Record", "Chart", "load_study", "make_study", "SUMMARIES"]

SUMMARIES = ("min", "max", "mean", "final")
# study.csv's columns besides the parameters and the recorded steps.csv summaries
# (docs/user-guide.md, "Studies"): every row's, then those of final_state, check_frames
# and a reference run
ROW_COLUMNS = ("run", "status", "error", "steps_done", "steps_planned", "wall_s",
               "newton_iterations", "steps_not_converged", "folder", "action",
               "inputs_sha256", "elapsed_s", "cpu_s")
FINAL_STATE_COLUMNS = ("final_time", "final_centre_x", "final_centre_y", "final_centre_z",
                       "final_max_speed", "final_positions_sha256")
FRAME_COLUMNS = ("frames_clean", "intersections", "inverted_tets", "below_plane")
REFERENCE_COLUMNS = ("error_rms", "error_max", "error_frames")
MAX_RUNS = 100_000
_TOP = ("study", "vary", "record", "reference", "chart")


class Axis(Struct, frozen=True):
    """Keys that change together: ``values[i]`` holds the i-th value of each key."""

    keys: tuple[str, ...]
    values: tuple[tuple, ...]


class Record(Struct, frozen=True):
    """What each run's study.csv row holds beyond its parameters, status and cost."""

    columns: tuple[str, ...] = ()
    summaries: tuple[str, ...] = SUMMARIES
    check_frames: bool = False
    final_state: bool = True


class Chart(Struct, frozen=True):
    x: str
    y: str = "wall_s"
    log_x: bool | None = None  # None: log when the values span a factor of 10 or more
    log_y: bool = False


class StudySpec(Struct, frozen=True):
    path: Path  # the study file, absolute
    scene: Path  # the base scene, absolute
    axes: tuple[Axis, ...]
    record: Record
    chart: Chart
    output: Path | None = None  # absolute
    steps: int | None = None
    fixed: dict = field(default_factory=dict)  # overrides of every run
    reference: dict | None = None  # the reference run's overrides (over ``fixed``)

    @property
    def keys(self) -> tuple[str, ...]:
        """Every varied key, axis by axis."""
        return tuple(k for a in self.axes for k in a.keys)

    @property
    def columns(self) -> tuple[str, ...]:
        """Every column study.csv can have (the chart's y must be one of them)."""
        rec = self.record
        return (*ROW_COLUMNS, *self.keys,
                *(f"{c}_{s}" for c in rec.columns for s in rec.summaries),
                *(FINAL_STATE_COLUMNS if rec.final_state else ()),
                *(FRAME_COLUMNS if rec.check_frames else ()),
                *(REFERENCE_COLUMNS if self.reference is not None else ()))

    def points(self) -> list[dict]:
        """Every run's overrides of the varied keys: the product of the axes."""
        out = [{}]
        for axis in self.axes:
            out = [{**p, **dict(zip(axis.keys, values))} for p in out
                   for values in axis.values]
        return out


class _Reader(KeyedReader):
    def __init__(self, path: Path, text: str):
        super().__init__(path, locate_keys(text))

    def number(self, v, key: str) -> float | int:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(key, f"{key} must be a finite number, got {excerpt(repr(v))}")
        return v

    def values(self, v, key: str) -> tuple:
        """A list of values, or a range table."""
        if isinstance(v, list):
            if not v:
                self.fail(key, f"{key} lists no values")
            return tuple(v)
        if not isinstance(v, dict):
            self.fail(key, f"{key} must be a list of values or a range "
                           "{start, stop, num} / {start, stop, step}")
        t = self.table(v, key, ("start", "stop", "num", "step", "spacing"))
        if "start" not in t or "stop" not in t or ("num" in t) == ("step" in t):
            self.fail(key, f"{key}: a range needs start, stop and one of num or step")
        start, stop = self.number(t["start"], f"{key}.start"), self.number(t["stop"],
                                                                           f"{key}.stop")
        if "step" in t:
            return self._stepped(start, stop, self.number(t["step"], f"{key}.step"), key)
        num = t["num"]
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= MAX_RUNS:
            self.fail(f"{key}.num", f"{key}.num must be a whole number from 1 to {MAX_RUNS}")
        spacing = t.get("spacing", "linear")
        if spacing not in ("linear", "log"):
            self.fail(f"{key}.spacing", f"{key}.spacing must be \"linear\" or \"log\"")
        if spacing == "log" and not (start > 0 and stop > 0):
            self.fail(key, f"{key}: a log range needs start and stop above 0")
        if num == 1:
            return (start,)
        if spacing == "log":
            if math.isfinite(stop / start):
                return tuple(start * (stop / start) ** (i / (num - 1)) for i in range(num))
            a, b = math.log(start), math.log(stop)  # the ratio overflows: in logarithms
            return self._finite(tuple(math.exp(a + (b - a) * i / (num - 1))
                                      for i in range(num)), key)
        if math.isfinite(stop - start):
            return tuple(start + (stop - start) * i / (num - 1) for i in range(num))
        # the span overflows (+-1e308): weighted, every value finite
        return self._finite(tuple(start * (1 - i / (num - 1)) + stop * (i / (num - 1))
                                  for i in range(num)), key)

    def _stepped(self, start, stop, step, key: str) -> tuple:
        if step == 0 or (stop - start) / step < 0:
            self.fail(f"{key}.step", f"{key}.step must lead from start to stop")
        count = (stop - start) / step * (1 + 1e-12)  # inf where the span or it overflows
        if not count < MAX_RUNS:
            self.fail(key, f"{key} makes more than {MAX_RUNS} values")
        n = math.floor(count) + 1
        ints = all(isinstance(x, int) for x in (start, stop, step))
        return self._finite(tuple((start + i * step) if ints else float(start + i * step)
                                  for i in range(n)), key)

    def _finite(self, values: tuple, key: str) -> tuple:
        bad = next((v for v in values if not math.isfinite(v)), None)
        if bad is not None:
            self.fail(key, f"{key} makes the value {bad!r}: a range's values must be finite")
        return values


def _flat(table: dict, is_leaf=lambda v: not isinstance(v, dict), prefix="") -> dict:
    """``{"time": {"dt": x}}`` (TOML's reading of an unquoted ``time.dt = x``) as
    ``{"time.dt": x}``; ``is_leaf`` says which tables are values (a range)."""
    out = {}
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else str(k)
        if is_leaf(v):
            out[name] = v
        else:
            out.update(_flat(v, is_leaf, name))
    return out


def _is_range_or_value(v) -> bool:
    return not isinstance(v, dict) or "start" in v or "stop" in v


def _axes(r: _Reader, data) -> tuple[Axis, ...]:
    if not isinstance(data, list) or not data or not all(isinstance(a, dict) for a in data):
        r.fail("vary", "a study needs at least one [[vary]] table of parameters")
    axes = []
    for i, a in enumerate(data):
        key = f"vary[{i}]"
        a = _flat(a, _is_range_or_value)
        if not a:
            r.fail(key, f"{key} names no parameter")
        columns = [r.values(v, f"{key}.{k}") for k, v in a.items()]
        if len({len(c) for c in columns}) > 1:
            r.fail(key, f"{key}: keys of one [[vary]] table change together, so they need "
                        f"as many values each (got {', '.join(str(len(c)) for c in columns)})"
                        "; put them in tables of their own for every combination")
        axes.append(Axis(tuple(a), tuple(zip(*columns))))
    seen: list[str] = [k for a in axes for k in a.keys]
    twice = sorted({k for k in seen if seen.count(k) > 1})
    if twice:
        r.fail("vary", f"'{excerpt(twice[0])}' is varied in two [[vary]] tables")
    if math.prod(len(a.values) for a in axes) > MAX_RUNS:
        r.fail("vary", f"the study makes more than {MAX_RUNS} runs")
    return tuple(axes)


def _record(r: _Reader, data) -> Record:
    from ..io.csv_log import STEP_COLUMNS

    t = r.table(data, "record", ("columns", "summaries", "check_frames", "final_state"))
    columns = t.get("columns", [])
    if not isinstance(columns, list):
        r.fail("record.columns", "record.columns must be a list of steps.csv columns")
    for c in columns:
        if c not in STEP_COLUMNS:
            r.fail("record.columns", f"record.columns: '{excerpt(c)}' is no steps.csv column"
                                     f"{suggest(str(c), STEP_COLUMNS)}")
    summaries = t.get("summaries", list(SUMMARIES))
    if not isinstance(summaries, list) or not summaries or any(
            s not in SUMMARIES for s in summaries):
        r.fail("record.summaries", f"record.summaries must list some of {', '.join(SUMMARIES)}")
    return Record(tuple(columns), tuple(summaries),
                  r.boolean(t.get("check_frames", False), "record.check_frames"),
                  r.boolean(t.get("final_state", True), "record.final_state"))


def _chart(r: _Reader, data, keys) -> Chart:
    t = r.table(data, "chart", ("x", "y", "log_x", "log_y"))
    x = t.get("x", keys[0])
    if x not in keys:
        r.fail("chart.x", f"chart.x must be a varied key ({', '.join(keys)}), got "
                          f"'{excerpt(x)}'")
    y = t.get("y", "wall_s")
    if not isinstance(y, str):
        r.fail("chart.y", "chart.y must name a study.csv column")
    log_x = t.get("log_x")
    return Chart(x, y, None if log_x is None else r.boolean(log_x, "chart.log_x"),
                 r.boolean(t.get("log_y", False), "chart.log_y"))


def _overrides(r: _Reader, data, key: str) -> dict:
    if not isinstance(data, dict):
        r.fail(key, f"{key} must be a table of dotted scene keys and values")
    return _flat(data)


def load_study(path) -> StudySpec:
    """Read and check a study file (the scene keys are checked when runs are planned)."""
    from ..scene import read_scene_text

    path = Path(path).absolute()
    text = read_scene_text(path, kind="study file")  # a scene file's rules: one reader
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(path, None, f"invalid TOML: {exc}") from None
    r = _Reader(path, text)
    r.table(doc, "", _TOP)
    study = r.table(doc.get("study", {}), "study", ("scene", "output", "steps", "set"))
    if not isinstance(study.get("scene"), str):
        r.fail("study", "[study] needs scene = \"path of the base scene\"")
    scene = Path(os.path.normpath(path.parent / study["scene"]))
    if not scene.is_file():
        found = "not found" if not scene.exists() else (
            "is a folder, not a scene file" if scene.is_dir() else
            "is not a regular file (a device, a pipe or a socket), so it cannot be a scene file")
        r.fail("study.scene", f"study.scene: '{excerpt(study['scene'], 80)}' {found} "
                              f"(relative to {path.parent})")
    steps = study.get("steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int)
                              or steps < 1):
        r.fail("study.steps", "study.steps must be a whole number >= 1")
    output = study.get("output")
    if output is not None and not isinstance(output, str):
        r.fail("study.output", "study.output must be a folder path")
    axes = _axes(r, doc.get("vary"))
    keys = tuple(k for a in axes for k in a.keys)
    reference = None
    if "reference" in doc:
        ref = r.table(doc["reference"], "reference", ("set",))
        reference = _overrides(r, ref.get("set", {}), "reference.set")
    spec = StudySpec(path, scene, axes, _record(r, doc.get("record", {})),
                     _chart(r, doc.get("chart", {}), keys),
                     Path(os.path.normpath(path.parent / output)) if output else None, steps,
                     _overrides(r, study.get("set", {}), "study.set"), reference)
    if spec.chart.y not in spec.columns:
        r.fail("chart.y", chart_y_problem(spec))
    return spec


def chart_y_problem(spec: StudySpec) -> str:
    """Why the chart's y names no column of the study's study.csv."""
    y = spec.chart.y
    return (f"chart.y: '{excerpt(y)}' is no column of this study's study.csv"
            f"{suggest(y, spec.columns)} (its columns: run, status, the varied keys, "
            "steps_done, wall_s, newton_iterations, ..., and what [record] and "
            "[reference] add)")


def make_study(scene, vary, *, steps: int | None = None, fixed: dict | None = None,
               record: Record | None = None, reference: dict | None = None,
               chart: Chart | None = None) -> StudySpec:
    """A study built in Python rather than read from a file: ``vary`` is one table of
    keys and value lists (they change together, as one ``[[vary]]`` table) or a list of
    such tables (every combination); the rest as in the file."""
    tables = [vary] if isinstance(vary, dict) else list(vary)
    axes = []
    for t in tables:
        columns = [tuple(v) for v in t.values()]
        if not columns or len({len(c) for c in columns}) != 1 or not columns[0]:
            raise ValueError("each table of vary needs keys with as many values each")
        axes.append(Axis(tuple(t), tuple(zip(*columns))))
    keys = [k for a in axes for k in a.keys]
    scene = Path(os.path.abspath(scene))
    spec = StudySpec(scene.with_name(f"{scene.stem}-study.toml"), scene, tuple(axes),
                     record or Record(), chart or Chart(keys[0]), None, steps,
                     dict(fixed or {}), None if reference is None else dict(reference))
    if spec.chart.y not in spec.columns:
        raise ValueError(chart_y_problem(spec))
    return spec
