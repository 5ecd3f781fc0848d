"""``checkpoint.npz``: the solver state a run can be resumed from.

A step depends on the previous one only through the simulation's ``State``: positions,
velocities and accelerations (Newmark needs aₙ), the step counter and the simulated time
(the boundary conditions' clock), the barrier stiffness κ (adapted and carried from step
to step), the previous step's non-inertial displacement (warm start 3 and 4), BDF2's
step before (xₙ₋₁, vₙ₋₁, hₙ₋₁), and with adaptive steps the next step's length and the
count of rejected attempts. Friction's
lagged normal forces and tangent bases are recomputed from xₙ at the start of every step,
so they are not part of it. Everything is stored as the exact doubles, which is why a
resumed run repeats the uninterrupted one to round-off.

The run command writes a checkpoint with a frame at most every few seconds of wall time,
at the last step and when it is interrupted, always after that step's frame and CSV rows
are forced to disk; the file is replaced atomically, so it is never half written. It carries a format version and the digest of the run's inputs
(the resolved scene and the bytes of every mesh), and :mod:`ipcsim.io.resume` checks it
against the folder's frames and logs before ``--resume`` changes anything; then rows and
frames of steps after the checkpoint are dropped (they are recomputed).
"""

from __future__ import annotations

import io
import re
import zipfile
from pathlib import Path

import numpy as np

from ..atomic import atomic_write_bytes
from ..errors import IpcsimError

__all__ = ["CHECKPOINT_NAME", "CheckpointError", "FORMAT_VERSION", "read_checkpoint",
           "write_checkpoint"]

CHECKPOINT_NAME = "checkpoint.npz"
FORMAT_VERSION = 3  # 2: with the inputs' digest; 3: time, BDF2's history, h_next, rejected
_DIGEST = re.compile(r"[0-9a-f]{64}\Z")


class CheckpointError(IpcsimError):
    """No usable checkpoint in an output folder, or one that does not fit it."""


def write_checkpoint(folder, state, inputs_sha256: str, *, fsync: bool = True) -> Path:
    """Store ``state`` (a ``Simulation.State``) as ``folder/checkpoint.npz``, with the
    digest of the run's inputs (``ipcsim.scene.digest.inputs_digest``)."""
    n = len(state.x)
    dx = state.dx_elastic
    buffer = io.BytesIO()
    history = state.history
    none = np.zeros((0, 3))
    np.savez(buffer, format_version=FORMAT_VERSION, inputs_sha256=np.str_(inputs_sha256),
             step=state.step, kappa=state.kappa, x=state.x, v=state.v, a=state.a,
              dx_elastic=none if dx is None else dx, num_vertices=n,
              time=float(state.time), h_next=float(state.h_next),
              rejected=int(state.rejected),
              x_prev=none if history is None else history.x,
              v_prev=none if history is None else history.v,
              h_prev=0.0 if history is None else float(history.h),
              plane_origins=none if state.plane_origins is None else state.plane_origins)
    return atomic_write_bytes(Path(folder) / CHECKPOINT_NAME, buffer.getvalue(), fsync=fsync)


def _load(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as data:
            return {key: np.asarray(data[key]) for key in data.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise CheckpointError(f"{path}: unreadable checkpoint "
                              f"({type(exc).__name__}: {str(exc)[:80]})") from None


def _scalar(ck: dict, key: str, kind: str, path: Path):
    a = ck.get(key)
    if a is None:
        raise CheckpointError(f"{path}: damaged checkpoint (no '{key}')")
    if a.shape != () or a.dtype.kind not in kind:
        raise CheckpointError(f"{path}: damaged checkpoint ('{key}' is not a single "
                              f"{'integer' if kind == 'iu' else 'number'})")
    return a.item()


def _positions(ck: dict, key: str, n: int, path: Path, allow_empty=False) -> np.ndarray:
    a = ck.get(key)
    if a is None:
        raise CheckpointError(f"{path}: damaged checkpoint (no '{key}')")
    if allow_empty and a.shape == (0, 3):
        return a.astype(np.float64)
    if a.shape != (n, 3) or a.dtype.kind != "f" or not np.isfinite(a).all():
        raise CheckpointError(f"{path}: damaged checkpoint ('{key}' is not {n} finite "
                              "3-D vectors)")
    return a.astype(np.float64)


def read_checkpoint(folder) -> dict:
    """The state stored in ``folder/checkpoint.npz``, checked to be whole: ``step``,
    ``kappa``, ``x``, ``v``, ``a``, ``dx_elastic`` (None when the run had not completed a
    step, or its warm start reads none), ``time``, ``h_next``, ``rejected``, ``history``
    ((xₙ₋₁, vₙ₋₁, hₙ₋₁), None without one) and ``inputs_sha256``. Anything else is a
    :class:`CheckpointError`."""
    path = Path(folder) / CHECKPOINT_NAME
    if not path.is_file():
        what = "is not a file" if path.exists() else "not found"
        raise CheckpointError(f"{folder}: nothing to resume ({CHECKPOINT_NAME} {what}); "
                              "run without --resume")
    ck = _load(path)
    version = _scalar(ck, "format_version", "iu", path) if "format_version" in ck else None
    if version != FORMAT_VERSION:
        raise CheckpointError(f"{path}: checkpoint format {version} is not {FORMAT_VERSION} "
                              "(written by another ipcsim version); run again with "
                              "--overwrite")
    digest = ck.get("inputs_sha256")
    if digest is None or digest.shape != () or digest.dtype.kind != "U" \
            or not _DIGEST.match(str(digest)):
        raise CheckpointError(f"{path}: damaged checkpoint (no digest of the inputs)")
    step = _scalar(ck, "step", "iu", path)
    kappa = _scalar(ck, "kappa", "fiu", path)
    t, h_next, h_prev = (_scalar(ck, key, "f", path) for key in ("time", "h_next", "h_prev"))
    rejected = _scalar(ck, "rejected", "iu", path)
    if step < 0 or not np.isfinite(kappa) or kappa < 0 or rejected < 0 \
            or not all(np.isfinite(q) and q >= 0 for q in (t, h_next, h_prev)):
        raise CheckpointError(f"{path}: damaged checkpoint (step {step}, kappa {kappa}, "
                              f"time {t}, h_next {h_next}, h_prev {h_prev})")
    n = _scalar(ck, "num_vertices", "iu", path)
    x = _positions(ck, "x", n, path)
    dx = _positions(ck, "dx_elastic", n, path, allow_empty=True)
    x_prev = _positions(ck, "x_prev", n, path, allow_empty=True)
    v_prev = _positions(ck, "v_prev", n, path, allow_empty=True)
    if len(x_prev) != len(v_prev) or (len(x_prev) > 0) != (h_prev > 0):
        raise CheckpointError(f"{path}: damaged checkpoint (an incomplete step before)")
    return {"step": int(step), "kappa": float(kappa), "x": x,
            "v": _positions(ck, "v", n, path), "a": _positions(ck, "a", n, path),
            "dx_elastic": dx if len(dx) else None, "inputs_sha256": str(digest),
            "time": float(t), "h_next": float(h_next), "rejected": int(rejected),
            "history": (x_prev, v_prev, float(h_prev)) if len(x_prev) else None,
            # a 2D scene's moving lines (none in a checkpoint of an earlier version)
            "plane_origins": (np.asarray(ck["plane_origins"], dtype=float).reshape(-1, 3)
                              if "plane_origins" in ck and len(ck["plane_origins"])
                              else None)}
