"""``checkpoint.npz``: the solver state a run can be resumed from.

A step depends on the previous one only through the simulation's ``State``: positions,
velocities and accelerations (Newmark needs aₙ), the step counter (the boundary
conditions' clock, t = step·h), the barrier stiffness κ (adapted and carried from step to
step) and the previous step's non-inertial displacement (warm start 3 and 4). Friction's
lagged normal forces and tangent bases are recomputed from xₙ at the start of every step,
so they are not part of it. Everything is stored as the exact doubles, which is why a
resumed run repeats the uninterrupted one to round-off.

The run command writes a checkpoint with every frame and when it is interrupted, always
after that step's frame and CSV rows are on disk; the file is replaced atomically, so it
is never half written. On resume, rows and frames of steps after the checkpoint are
dropped (they are recomputed).
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from ..errors import IpcsimError
from ..atomic import atomic_write_bytes

__all__ = ["CHECKPOINT_NAME", "CheckpointError", "read_checkpoint", "write_checkpoint"]

CHECKPOINT_NAME = "checkpoint.npz"
FORMAT_VERSION = 1


class CheckpointError(IpcsimError):
    """No usable checkpoint in an output folder."""


def write_checkpoint(folder, state, *, fsync: bool = True) -> Path:
    """Store ``state`` (a ``Simulation.State``) as ``folder/checkpoint.npz``."""
    n = len(state.x)
    dx = state.dx_elastic
    buffer = io.BytesIO()
    np.savez(buffer, format_version=FORMAT_VERSION, step=state.step, kappa=state.kappa,
             x=state.x, v=state.v, a=state.a,
             dx_elastic=np.zeros((0, 3)) if dx is None else dx, num_vertices=n)
    return atomic_write_bytes(Path(folder) / CHECKPOINT_NAME, buffer.getvalue(), fsync=fsync)


def read_checkpoint(folder) -> dict:
    """The arrays and numbers of ``folder/checkpoint.npz``; ``dx_elastic`` is None when
    the run had not completed a step."""
    path = Path(folder) / CHECKPOINT_NAME
    if not path.is_file():
        raise CheckpointError(f"{folder}: nothing to resume (no {CHECKPOINT_NAME}); "
                              "run without --resume")
    try:
        with np.load(path) as data:
            ck = {key: data[key] for key in data.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise CheckpointError(f"{path}: unreadable checkpoint ({exc})") from exc
    if int(ck.get("format_version", -1)) != FORMAT_VERSION:
        raise CheckpointError(f"{path}: checkpoint format {ck.get('format_version')} is not "
                              f"{FORMAT_VERSION}; run again without --resume")
    return {
        "step": int(ck["step"]), "kappa": float(ck["kappa"]),
        "x": ck["x"], "v": ck["v"], "a": ck["a"],
        "dx_elastic": ck["dx_elastic"] if len(ck["dx_elastic"]) else None,
    }
