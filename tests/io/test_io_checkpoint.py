"""checkpoint.npz: written whole, read back exactly, and every damaged one refused with
a CheckpointError naming the file (never a KeyError, a zip error or a wrong state)."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from ipcsim.io.checkpoint import (
    CHECKPOINT_NAME,
    FORMAT_VERSION,
    CheckpointError,
    read_checkpoint,
    write_checkpoint,
)
from ipcsim.simulation import State
from ipcsim.solver.integrator import StepHistory

DIGEST = "ab" * 32


def state(step=3, dx=True) -> State:
    rng = np.random.default_rng(1)
    x, v, a = (rng.standard_normal((5, 3)) for _ in range(3))
    return State(x, v, a, step, 12.5, rng.standard_normal((5, 3)) if dx else None)


def test_round_trip_is_exact(tmp_path):
    s = state()
    write_checkpoint(tmp_path, s, DIGEST)
    ck = read_checkpoint(tmp_path)
    assert ck["step"] == 3 and ck["kappa"] == 12.5 and ck["inputs_sha256"] == DIGEST
    for key in ("x", "v", "a", "dx_elastic"):
        assert np.array_equal(ck[key], getattr(s, key))
    assert ck["history"] is None and ck["time"] == 0.0 and ck["rejected"] == 0
    write_checkpoint(tmp_path, state(0, dx=False), DIGEST)
    assert read_checkpoint(tmp_path)["dx_elastic"] is None


def test_round_trip_of_bdf2_and_adaptive_steps_is_exact(tmp_path):
    """BDF2's step before, the time, the next step's length and the rejected count."""
    rng = np.random.default_rng(2)
    history = StepHistory(rng.standard_normal((5, 3)), rng.standard_normal((5, 3)), 0.0123)
    s = msgspec.structs.replace(state(), history=history, time=0.1 + 0.2, h_next=0.00731,
                                rejected=4)
    write_checkpoint(tmp_path, s, DIGEST)
    ck = read_checkpoint(tmp_path)
    x_prev, v_prev, h_prev = ck["history"]
    assert np.array_equal(x_prev, history.x) and np.array_equal(v_prev, history.v)
    assert (h_prev, ck["time"], ck["h_next"], ck["rejected"]) == (0.0123, 0.1 + 0.2,
                                                                  0.00731, 4)


def rewrite(folder, **changes):
    path = folder / CHECKPOINT_NAME
    with np.load(path) as data:
        ck = {k: data[k] for k in data.files}
    for key, value in changes.items():
        if value is None:
            ck.pop(key)
        else:
            ck[key] = value
    with open(path, "wb") as f:
        np.savez(f, **ck)


@pytest.mark.parametrize("changes,fragment", [
    ({"x": None}, "no 'x'"),
    ({"step": np.float64(2.5)}, "'step' is not a single integer"),
    ({"step": np.array([1, 2])}, "'step' is not a single integer"),
    ({"step": np.int64(-1)}, "step -1"),
    ({"kappa": np.float64(np.nan)}, "kappa nan"),
    ({"time": np.float64(-1.0)}, "time -1.0"),
    ({"h_prev": np.float64(0.01)}, "an incomplete step before"),
    ({"rejected": np.float64(1.0)}, "'rejected' is not a single integer"),
    ({"x": np.float64(1.0)}, "'x' is not 5 finite"),
    ({"v": np.zeros((4, 3))}, "'v' is not 5 finite"),
    ({"a": np.full((5, 3), np.inf)}, "'a' is not 5 finite"),
    ({"x": np.full((5, 3), "a")}, "'x' is not 5 finite"),
    ({"inputs_sha256": None}, "no digest"),
    ({"inputs_sha256": np.str_("xyz")}, "no digest"),
    ({"format_version": np.int64(1)}, "format 1"),
    ({"format_version": None}, "format None"),
    ({"num_vertices": np.int64(4)}, "'x' is not 4 finite"),
], ids=lambda v: str(v)[:30])
def test_damaged_checkpoints_are_refused(tmp_path, changes, fragment):
    write_checkpoint(tmp_path, state(), DIGEST)
    rewrite(tmp_path, **changes)
    with pytest.raises(CheckpointError, match=fragment.replace("(", r"\(")) as err:
        read_checkpoint(tmp_path)
    assert CHECKPOINT_NAME in str(err.value)


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 not really", b"hello"])
def test_a_checkpoint_that_is_not_an_npz_is_refused(tmp_path, content):
    (tmp_path / CHECKPOINT_NAME).write_bytes(content)
    with pytest.raises(CheckpointError, match="unreadable checkpoint"):
        read_checkpoint(tmp_path)


def test_an_object_array_is_not_unpickled(tmp_path):
    write_checkpoint(tmp_path, state(), DIGEST)
    rewrite(tmp_path, x=np.array([object()] * 5, dtype=object))
    with pytest.raises(CheckpointError, match="unreadable"):
        read_checkpoint(tmp_path)


def test_no_checkpoint_or_a_folder_in_its_place(tmp_path):
    with pytest.raises(CheckpointError, match="nothing to resume"):
        read_checkpoint(tmp_path)
    (tmp_path / CHECKPOINT_NAME).mkdir()
    with pytest.raises(CheckpointError, match="is not a file"):
        read_checkpoint(tmp_path)
    assert FORMAT_VERSION == 3
