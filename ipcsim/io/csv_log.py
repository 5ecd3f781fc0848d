"""Per-step and per-Newton-iteration CSV logs (``steps.csv``, ``newton.csv``).

Each log has a fixed column set (documented in docs/output-format.md), is opened once
per run, writes its header once and appends one complete row per call, flushed to the
operating system (and optionally fsync'd) before the call returns, so the file on disk
always ends with a whole row.

Cell format: integers as decimal, booleans as ``1``/``0``, floats as the shortest
digits that read back as the same double (e.g. ``0.1``, ``1e-8``, ``0.00002648``,
``2.5e16``; msgspec's JSON number text, a cell in a third of ``repr``'s time:
a tiny scene's run formats some 14,000 cells), ``nan``, ``inf``, ``-inf``, and a
missing value as an empty cell. A float cell always contains ``.``, ``e``, ``nan`` or
``inf``, so integer and float columns stay distinguishable on reading.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from msgspec.json import Encoder
import numpy as np

from ..atomic import atomic_write_text

__all__ = [
    "NEWTON_COLUMNS",
    "STEP_COLUMNS",
    "CsvLog",
    "NewtonLog",
    "StepLog",
    "format_cell",
    "read_csv",
]

STEP_COLUMNS: tuple[str, ...] = (
    "step",
    "time",
    "dt",
    "newton_iterations",
    "converged",
    "hit_iteration_cap",
    "line_search_min_alpha",
    "kappa",
    "dhat",
    "min_distance",
    "contacts_plane",
    "contacts_point_triangle",
    "contacts_edge_edge",
    "contacts_total",
    "energy",
    "kinetic_energy",
    "elastic_energy",
    "wall_s",
    "wall_energy_s",
    "wall_assembly_s",
    "wall_solve_s",
    "wall_ccd_line_search_s",
    "wall_contact_set_s",
    "friction_contacts",
    "friction_iterations",
    "friction_energy",
    "error_estimate",
    "accepted",
)

NEWTON_COLUMNS: tuple[str, ...] = (
    "step",
    "iteration",
    "alpha",
    "step_inf_norm",
    "tolerance",
    "residual_ratio",
    "energy",
    "gradient_norm",
    "contacts_plane",
    "contacts_point_triangle",
    "contacts_edge_edge",
    "contacts_total",
    "kappa",
    "min_distance",
)


_NUMBER_TEXT = Encoder().encode


def float_cell(value: float) -> str:
    """A float's cell: its shortest round-trip digits, or nan, inf, -inf (JSON has none:
    its encoder would write null)."""
    return _NUMBER_TEXT(value).decode() if math.isfinite(value) else repr(value)


def format_cell(value) -> str:
    """Text of one CSV cell; raises TypeError for anything that is not a number."""
    kind = type(value)  # the common cells first: the ABC checks below cost a microsecond
    if kind is float:
        return float_cell(value)
    if kind is int:
        return str(value)
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return float_cell(float(value))
    raise TypeError(f"a CSV log cell must be a number, bool or None, got {type(value).__name__}")


class CsvLog:
    """An append-only CSV file with a fixed column set.

    ``append(row)`` takes a mapping from column name to value; columns it leaves out
    are written empty, and a key that is not a column raises ``ValueError`` (a
    misspelt column would otherwise vanish silently). Use as a context manager or
    call ``close()``.
    """

    def __init__(self, path: str | os.PathLike, columns: Sequence[str], *, fsync: bool = False,
                 keep_rows=None):
        """``keep_rows(row) -> bool``: continue an existing file (a resumed run), keeping
        the rows it accepts (``row`` maps column to cell text) and dropping the rest; the
        file's header must be this log's columns."""
        if len(set(columns)) != len(columns):
            raise ValueError("CSV columns must be unique")
        self.path = Path(path)
        self.columns = tuple(columns)
        self._known = frozenset(self.columns)
        self.fsync = fsync
        self.rows_written = 0
        header = ",".join(self.columns)
        if keep_rows is not None:
            self._keep(header, keep_rows)
            self._file = open(self.path, "a", encoding="utf-8", newline="")
            return
        # newline="": rows end in "\n" on every platform
        self._file = open(self.path, "w", encoding="utf-8", newline="")
        self._write_line(header)

    def _keep(self, header: str, keep_rows) -> None:
        """Rewrite the file (atomically) with only the rows ``keep_rows`` accepts; a
        last line cut short by a crash is dropped too."""
        text = self.path.read_text(encoding="utf-8") if self.path.is_file() else header + "\n"
        lines = text.split("\n")
        if lines[0] != header:
            raise ValueError(f"{self.path}: its columns are not this version's; "
                             "run again without --resume")
        complete = lines[1:-1]  # text after the last newline is an unfinished row
        kept = [ln for ln in complete
                if len(cells := ln.split(",")) == len(self.columns)
                and keep_rows(dict(zip(self.columns, cells)))]
        atomic_write_text(self.path, "\n".join([header, *kept]) + "\n", fsync=self.fsync)

    def _write_line(self, line: str) -> None:
        # one write per line, then flush: a reader never sees a partial row mid-run
        self._file.write(line + "\n")
        self._file.flush()
        if self.fsync:
            os.fsync(self._file.fileno())

    def sync(self) -> None:
        """Force the rows written so far to disk."""
        if not self._file.closed:
            self._file.flush()
            os.fsync(self._file.fileno())

    def append(self, row: Mapping[str, object]) -> None:
        """Write one row; see the class docstring for the rules."""
        self.append_rows((row,))

    def append_rows(self, rows) -> None:
        """Write several rows (a step's Newton iterations) with one write and one flush;
        nothing is written if any row is wrong."""
        if self._file.closed:
            raise ValueError(f"{self.path} is closed")
        lines = [self._line(row) for row in rows]
        if lines:
            self._write_line("\n".join(lines))
            self.rows_written += len(lines)

    def _line(self, row: Mapping[str, object]) -> str:
        if not self._known.issuperset(row):
            unknown = [k for k in row if k not in self._known]
            raise ValueError(
                f"unknown column(s) {', '.join(map(repr, unknown))} for {self.path.name}; "
                f"columns are: {', '.join(self.columns)}"
            )
        # most cells are floats: their text without a call of format_cell
        return ",".join([float_cell(v) if type(v) is float else format_cell(v)
                         for v in map(row.get, self.columns)])

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    @property
    def closed(self) -> bool:
        return self._file.closed

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class StepLog(CsvLog):
    """``steps.csv``: one row per time step, columns :data:`STEP_COLUMNS`.

    With adaptive time steps a row is an attempted step, ``accepted`` 0 for one that was
    tried again shorter.

    ``totals`` sums the file's rows (those a resumed run kept, and those appended):
    Newton iterations, steps that hit the iteration cap, accepted steps that did not
    converge, accepted and rejected steps, and the simulated time (of the last accepted
    step); run.json's totals, without reading the file back (2 ms of a tiny scene's
    run)."""

    FILE_NAME = "steps.csv"

    def __init__(self, path: str | os.PathLike, *, fsync: bool = False, keep_rows=None):
        self.totals = {"newton_iterations": 0, "hit_iteration_cap": 0, "not_converged": 0,
                       "accepted": 0, "rejected": 0, "simulated_time": 0.0}
        kept = None
        if keep_rows is not None:
            def kept(cells):  # cells: column -> text
                if not keep_rows(cells):
                    return False
                self._add_to_totals(*(float(cells[c]) if cells[c] else None
                                      for c in _TOTALLED))
                return True
        super().__init__(path, STEP_COLUMNS, fsync=fsync, keep_rows=kept)

    def append_rows(self, rows) -> None:
        rows = tuple(rows)
        super().append_rows(rows)
        for row in rows:
            self._add_to_totals(*map(row.get, _TOTALLED))

    def _add_to_totals(self, iterations, hit_cap, converged, accepted, t) -> None:
        """One row's part of the totals; an empty cell (None) adds nothing (an empty
        ``accepted``: an accepted step)."""
        totals = self.totals
        totals["newton_iterations"] += int(iterations or 0)
        totals["hit_iteration_cap"] += int(hit_cap or 0)
        if accepted is not None and not accepted:
            totals["rejected"] += 1
            return
        totals["accepted"] += 1
        totals["not_converged"] += int(converged is not None and not converged)
        if t is not None:
            totals["simulated_time"] = float(t)


# StepLog's totals
_TOTALLED = ("newton_iterations", "hit_iteration_cap", "converged", "accepted", "time")


class NewtonLog(CsvLog):
    """``newton.csv``: one row per Newton iteration, columns :data:`NEWTON_COLUMNS`."""

    FILE_NAME = "newton.csv"

    def __init__(self, path: str | os.PathLike, *, fsync: bool = False, keep_rows=None):
        super().__init__(path, NEWTON_COLUMNS, fsync=fsync, keep_rows=keep_rows)


def _is_int_text(cell: str) -> bool:
    s = cell[1:] if cell[:1] in "+-" else cell
    return s.isdigit()


def read_csv(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read a log back: column name -> array, in file order.

    A column whose every cell is an integer becomes ``int64``; any other column becomes
    ``float64`` with empty cells as NaN. Floats read back bit-for-bit as written.
    """
    with open(path, encoding="utf-8", newline="") as f:
        lines = f.read().splitlines()
    if not lines:
        raise ValueError(f"{path} is empty (no header)")
    columns = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:] if line]
    for i, r in enumerate(rows, start=2):
        if len(r) != len(columns):
            raise ValueError(f"{path}:{i}: {len(r)} cells, header has {len(columns)}")
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(columns):
        cells = [r[j] for r in rows]
        if cells and all(_is_int_text(c) for c in cells):
            out[name] = np.array([int(c) for c in cells], dtype=np.int64)
        else:
            out[name] = np.array([float(c) if c else math.nan for c in cells], dtype=np.float64)
    return out
