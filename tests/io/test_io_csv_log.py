from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcsim.io.csv_log import (
    NEWTON_COLUMNS,
    STEP_COLUMNS,
    CsvLog,
    NewtonLog,
    StepLog,
    format_cell,
    read_csv,
)


def test_step_log_round_trip_exact(tmp_path):
    path = tmp_path / "steps.csv"
    rows = [
        {"step": 1, "time": 0.1, "dt": 0.1, "newton_iterations": 7, "converged": True,
         "kappa": 1.2345678901234567e5, "min_distance": 1e-300, "energy": -0.30000000000000004},
        {"step": 2, "time": 0.2, "dt": 0.1, "newton_iterations": np.int64(100),
         "converged": np.bool_(False), "hit_iteration_cap": True,
         "kappa": np.float64(2 / 3), "min_distance": math.inf, "energy": math.nan},
    ]
    with StepLog(path) as log:
        for row in rows:
            log.append(row)
        assert log.rows_written == 2
    assert log.closed
    data = read_csv(path)
    assert tuple(data) == STEP_COLUMNS
    np.testing.assert_array_equal(data["step"], [1, 2])
    assert data["step"].dtype == np.int64
    np.testing.assert_array_equal(data["converged"], [1, 0])
    assert data["time"].tolist() == [0.1, 0.2]
    assert data["kappa"].tolist() == [1.2345678901234567e5, 2 / 3]
    assert data["min_distance"].tolist() == [1e-300, math.inf]
    assert data["energy"][0] == -0.30000000000000004
    assert math.isnan(data["energy"][1])
    # never given: empty cells, read back as NaN
    assert np.isnan(data["wall_s"]).all()
    assert data["hit_iteration_cap"][1] == 1 and np.isnan(data["hit_iteration_cap"][0])


def test_missing_values_are_empty_cells(tmp_path):
    path = tmp_path / "newton.csv"
    with NewtonLog(path) as log:
        log.append({"step": 3, "iteration": 0, "energy": 1.5})
    header, row = path.read_text().splitlines()
    assert header == ",".join(NEWTON_COLUMNS)
    cells = row.split(",")
    assert len(cells) == len(NEWTON_COLUMNS)
    assert cells[:3] == ["3", "0", ""]
    assert cells[NEWTON_COLUMNS.index("energy")] == "1.5"
    assert sum(c == "" for c in cells) == len(NEWTON_COLUMNS) - 3


def test_unknown_column_raises_and_writes_nothing(tmp_path):
    path = tmp_path / "steps.csv"
    with StepLog(path) as log:
        with pytest.raises(ValueError, match="newton_iters"):
            log.append({"step": 1, "newton_iters": 3})
        with pytest.raises(TypeError):
            log.append({"step": "one"})
    assert path.read_text() == ",".join(STEP_COLUMNS) + "\n"


def test_each_row_is_on_disk_when_append_returns(tmp_path):
    path = tmp_path / "steps.csv"
    log = StepLog(path, fsync=True)
    try:
        log.append({"step": 0})
        # read while the log is still open: the row must already be complete
        assert path.read_text().splitlines()[1].startswith("0,")
        log.append({"step": 1})
        assert read_csv(path)["step"].tolist() == [0, 1]
    finally:
        log.close()
    with pytest.raises(ValueError, match="closed"):
        log.append({"step": 2})


def test_rows_appended_together_are_written_whole_or_not_at_all(tmp_path):
    path = tmp_path / "newton.csv"
    with NewtonLog(path) as log:
        log.append_rows([{"step": 1, "iteration": i, "energy": 0.5 * i} for i in range(3)])
        assert log.rows_written == 3
        # on disk before the log closes, each row on its own line
        assert read_csv(path)["iteration"].tolist() == [0, 1, 2]
        with pytest.raises(ValueError, match="alfa"):
            log.append_rows([{"step": 2, "iteration": 0}, {"step": 2, "alfa": 1.0}])
        log.append_rows([])
        assert log.rows_written == 3
    data = read_csv(path)
    assert data["step"].tolist() == [1, 1, 1]
    assert data["energy"].tolist() == [0.0, 0.5, 1.0]


def test_header_only_file_reads_as_empty_columns(tmp_path):
    path = tmp_path / "newton.csv"
    NewtonLog(path).close()
    data = read_csv(path)
    assert tuple(data) == NEWTON_COLUMNS
    assert all(len(a) == 0 for a in data.values())


def test_duplicate_columns_rejected(tmp_path):
    with pytest.raises(ValueError):
        CsvLog(tmp_path / "x.csv", ["a", "a"])


def test_format_cell():
    assert format_cell(None) == ""
    assert format_cell(True) == "1"
    assert format_cell(np.int32(-4)) == "-4"
    assert format_cell(np.float32(0.1)) == repr(float(np.float32(0.1)))
    assert format_cell(1.0) == "1.0"  # a float stays recognisably a float
    assert [format_cell(v) for v in (math.nan, math.inf, -math.inf, -0.0, 1e-8)] == [
        "nan", "inf", "-inf", "-0.0", "1e-8"]


@settings(max_examples=500, deadline=None)
@given(st.floats())
def test_a_float_cell_reads_back_as_the_same_double_and_as_a_float(value):
    text = format_cell(value)
    assert any(mark in text for mark in (".", "e", "nan", "inf"))  # never an integer cell
    back = float(text)
    assert np.array(back).tobytes() == np.array(value).tobytes() or (
        math.isnan(value) and math.isnan(back))
    # no more digits than repr's, the shortest that read back
    assert _digits(text) <= _digits(repr(value))


def _digits(text: str) -> int:
    """Significant digits written (trailing zeros of an integral value count)."""
    mantissa = text.split("e")[0].replace("-", "").replace(".", "")
    return len(mantissa.lstrip("0"))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(allow_nan=False), min_size=1, max_size=5))
def test_any_double_round_trips(tmp_path_factory, values):
    path = tmp_path_factory.mktemp("csv") / "t.csv"
    with CsvLog(path, ["v"]) as log:
        for v in values:
            log.append({"v": v})
    back = read_csv(path)["v"]
    assert back.dtype == np.float64
    # bit-exact, including the sign of zero
    assert back.tobytes() == np.array(values, dtype=np.float64).tobytes()


def _totals_read_back(path):
    """run.json's totals as the file holds them (how they were taken before StepLog
    kept them): an empty ``accepted`` cell is an accepted step."""
    data = read_csv(path)
    accepted = data["accepted"] != 0
    converged = data["converged"]
    times = data["time"][accepted]
    return {"newton_iterations": int(np.nansum(data["newton_iterations"])),
            "hit_iteration_cap": int(np.nansum(data["hit_iteration_cap"])),
            "not_converged": int(np.sum(converged[accepted] == 0)),
            "accepted": int(accepted.sum()), "rejected": int((~accepted).sum()),
            "simulated_time": float(times[~np.isnan(times)][-1]) if
            (~np.isnan(times)).any() else 0.0}


def test_step_log_totals_are_those_of_its_rows_kept_and_appended(tmp_path):
    path = tmp_path / "steps.csv"
    rows = [{"step": k, "time": 0.1 * k, "newton_iterations": k + 2, "converged": k != 3,
             "hit_iteration_cap": int(k == 3)} for k in range(1, 6)]
    rows[1] = {"step": 2}  # cells left empty count for nothing
    with StepLog(path) as log:
        log.append(rows[0])
        log.append_rows(rows[1:])
    assert log.totals == _totals_read_back(path) == {
        "newton_iterations": 3 + 5 + 6 + 7, "hit_iteration_cap": 1, "not_converged": 1,
        "accepted": 5, "rejected": 0, "simulated_time": 0.5}

    # a resumed run keeps steps 1..3 and appends a new step 4
    with StepLog(path, keep_rows=lambda cells: int(cells["step"]) <= 3) as log:
        assert log.totals == {"newton_iterations": 3 + 5, "hit_iteration_cap": 1,
                              "not_converged": 1, "accepted": 3, "rejected": 0,
                              "simulated_time": 0.1 * 3}
        log.append({"step": 4, "time": 0.4, "newton_iterations": 10,
                    "converged": np.bool_(False), "hit_iteration_cap": np.int64(1)})
    assert log.totals == _totals_read_back(path) == {
        "newton_iterations": 18, "hit_iteration_cap": 2, "not_converged": 2,
        "accepted": 4, "rejected": 0, "simulated_time": 0.4}


def test_step_log_totals_count_rejected_attempts_apart(tmp_path):
    """Adaptive steps: a rejected attempt (accepted 0) counts as rejected, not as a step
    that did not converge, and leaves the simulated time where it was."""
    path = tmp_path / "steps.csv"
    rows = [{"step": 1, "time": 0.01, "newton_iterations": 4, "converged": 1, "accepted": 1},
            {"step": 2, "time": 0.02, "newton_iterations": 50, "converged": 0,
             "hit_iteration_cap": 1, "accepted": 0},
            {"step": 2, "time": 0.015, "newton_iterations": 3, "converged": 1,
             "accepted": 0},
            {"step": 2, "time": 0.015, "newton_iterations": 3, "converged": 1,
             "accepted": 1}]
    with StepLog(path) as log:
        log.append_rows(rows)
    assert log.totals == _totals_read_back(path) == {
        "newton_iterations": 60, "hit_iteration_cap": 1, "not_converged": 0,
        "accepted": 2, "rejected": 2, "simulated_time": 0.015}
