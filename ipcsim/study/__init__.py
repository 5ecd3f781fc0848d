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
from .runs import RunTask, cached_row, plan, refuse_replacing
from .spec import Chart, Record, StudySpec, load_study, make_study
from .table import CHART_NAME, TABLE_NAME, chart, reference_errors, write_table

__all__ = ["load_study", "make_study", "run_study", "study_folder", "StudySpec",
           "StudyResult", "Record", "Chart", "default_output"]


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


def study_folder(study: StudySpec, requested, overwrite: bool = False) -> Path:
    """The study's folder, checked before anything is written
    (``io.output_folder.resolve_study_folder``)."""
    from ..io.output_folder import resolve_study_folder

    shared = (("the current directory", Path.cwd()),
              ("the study file's folder", study.path.parent),
              ("the scene's folder", study.scene.parent))
    return resolve_study_folder(requested, shared, overwrite=overwrite,
                                study_name=study.path.name)


def run_study(study: StudySpec, out: Path, executor, progress_mode: str = "off",
              say=lambda message: None, overwrite: bool = False) -> StudyResult:
    """Execute the study into ``out`` (see the module's docstring); ``overwrite`` runs it
    afresh (the study's own files in ``out`` are replaced, once it has been planned)."""
    from ..io.output_folder import clear_study_folder, hold_folder, mark_study_folder

    out = study_folder(study, out, overwrite)
    tasks, reference = plan(study, out)
    everything = tasks + ([reference] if reference else [])
    with hold_folder(out, "study folder"):
        if overwrite:
            clear_study_folder(out)
        else:
            refuse_replacing(everything)
        mark_study_folder(out, study.path.name)
        final, ran = _execute(study, out, everything, executor, progress_mode, say)
    runs = [r for r in final if r.get("run") != "reference"]  # its error is 0 by definition
    picture = chart(out / CHART_NAME, runs, study.chart.x, study.chart.y, study.keys,
                    log_x=study.chart.log_x, log_y=study.chart.log_y,
                    title=f"{study.path.stem}: {study.chart.y} against {study.chart.x}")
    failed = sum(r.get("status") != "ok" for r in final)
    return StudyResult(out, tuple(final), ran, failed, out / TABLE_NAME, picture)


def _table(everything: list[RunTask], rows: dict) -> list[dict]:
    """study.csv's rows: every run that has one, in the study's order."""
    return [_row_for(t, rows[t.digest]) for t in everything if t.digest in rows]


def _execute(study, out, everything, executor, progress_mode, say) -> tuple[list, int]:
    """Run what is not finished yet, writing study.csv after each run and at the end;
    returns study.csv's rows (with the errors against the reference) and how many runs
    were executed."""
    from .executors import StudyProgress, interrupted_by_signals

    rows: dict[str, dict] = {}  # digest -> row
    for t in everything:
        cached = cached_row(t)
        if cached is not None:
            rows[t.digest] = {**cached, "action": "skipped"}
    todo = list({t.digest: t for t in everything if t.digest not in rows}.values())
    say(f"ipcsim sweep: {study.path.name} -> {out}: {len(everything)} runs, "
        f"{len(everything) - len(todo)} finished already"
        + (f", {len(todo)} on {executor.name}" if todo else ""))
    progress = StudyProgress(len(everything), len(everything) - len(todo), progress_mode)
    reference = everything[-1] if everything[-1].name == "reference" else None
    try:
        if todo:
            with interrupted_by_signals(), executor:
                for task, row in executor.results(todo, progress):
                    rows[task.digest] = row
                    progress.finished(task, row)
                    write_table(out / TABLE_NAME, _table(everything, rows), study.keys)
    except (KeyboardInterrupt, RunInterrupted):
        raise RunInterrupted(f"study interrupted; {len(rows)} of {len(everything)} runs are "
                             f"in {out / TABLE_NAME}; run the same `ipcsim sweep` again to "
                             "continue (finished runs are kept, interrupted ones "
                             "resume)") from None
    finally:
        progress.close()
        final = _table(everything, rows)
        if reference is not None and rows.get(reference.digest, {}).get("status") == "ok":
            reference_errors(final, rows[reference.digest])
        write_table(out / TABLE_NAME, final, study.keys)
    return final, len(todo)
