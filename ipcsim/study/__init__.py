"""Studies: many runs of one scene with some of its values varied, run on Dask (or in
this process), summarised into one table and a chart (docs/user-guide.md, "Studies").

``run_study(study, out, executor)`` plans the runs (each run's scene resolved and its
content digest taken here, so a bad key stops the study before anything runs), reuses
the rows of runs already finished, executes the rest, and writes ``study.csv`` after
every finished run and the chart at the end.
"""

from __future__ import annotations

from pathlib import Path

from msgspec import Struct

from ..errors import RunInterrupted
from .runs import RunTask, cached_row, plan
from .spec import Chart, Record, StudySpec, load_study, make_study
from .table import CHART_NAME, TABLE_NAME, chart, reference_errors, write_table

__all__ = ["load_study", "make_study", "run_study", "StudySpec", "StudyResult", "Record",
           "Chart", "default_output"]


class StudyResult(Struct, frozen=True):
    out: Path
    rows: tuple[dict, ...]  # study.csv's rows: the runs in order, then the reference
    ran: int  # runs executed by this call (the others were finished already)
    failed: int
    table: Path
    chart: Path | None


def default_output(study: StudySpec) -> Path:
    """``[study] output``, else ``output/<study-file-stem>``."""
    return study.output or Path("output").absolute() / study.path.stem


def _row_for(task: RunTask, row: dict) -> dict:
    """A row of a run that shares its scene (and folder) with another: its own name."""
    return {**row, "run": task.name, **task.parameters}


def run_study(study: StudySpec, out: Path, executor, progress_mode: str = "off",
              say=lambda message: None) -> StudyResult:
    """Execute the study into ``out`` (see the module's docstring)."""
    from .executors import StudyProgress

    out = Path(out).absolute()
    tasks, reference = plan(study, out)
    everything = tasks + ([reference] if reference else [])
    rows: dict[str, dict] = {}  # digest -> row
    for t in everything:
        cached = cached_row(t)
        if cached is not None:
            rows[t.digest] = {**cached, "action": "skipped"}
    todo = list({t.digest: t for t in everything if t.digest not in rows}.values())
    out.mkdir(parents=True, exist_ok=True)

    def table() -> list[dict]:
        return [_row_for(t, rows[t.digest]) for t in everything if t.digest in rows]

    say(f"ipcsim sweep: {study.path.name} -> {out}: {len(everything)} runs, "
        f"{len(everything) - len(todo)} finished already"
        + (f", {len(todo)} on {executor.name}" if todo else ""))
    progress = StudyProgress(len(everything), len(everything) - len(todo), progress_mode)
    try:
        if todo:
            with executor:
                for task, row in executor.results(todo, progress):
                    rows[task.digest] = row
                    progress.finished(task, row)
                    write_table(out / TABLE_NAME, table(), study.keys)
    except (KeyboardInterrupt, RunInterrupted):
        raise RunInterrupted(f"study interrupted; {len(rows)} of {len(everything)} runs are "
                             f"in {out / TABLE_NAME}; run the same `ipcsim sweep` again to "
                             "continue (finished runs are kept, interrupted ones "
                             "resume)") from None
    finally:
        progress.close()
        final = table()
        if reference is not None and rows.get(reference.digest, {}).get("status") == "ok":
            reference_errors(final, rows[reference.digest])
        write_table(out / TABLE_NAME, final, study.keys)
    runs = [r for r in final if r.get("run") != "reference"]  # its error is 0 by definition
    picture = chart(out / CHART_NAME, runs, study.chart.x, study.chart.y, study.keys,
                    log_x=study.chart.log_x, log_y=study.chart.log_y,
                    title=f"{study.path.stem}: {study.chart.y} against {study.chart.x}")
    failed = sum(r.get("status") != "ok" for r in final)
    return StudyResult(out, tuple(final), len(todo), failed, out / TABLE_NAME, picture)
