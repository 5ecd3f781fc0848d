"""Per-frame VTK output: one ``.vtu`` file per written frame plus a ``.pvd`` series.

The connectivity of a run never changes, so :class:`FrameWriter` takes it once and
encodes the ``<Cells>`` section a single time; each frame then only encodes the
positions and point data. Files are VTK XML UnstructuredGrid, binary (base64) with
zlib-compressed blocks and 64-bit headers, which ParaView, VTK/pyvista and meshio read.

Every file is written atomically (see :mod:`ipcsim.atomic`), and ``series.pvd`` is
rewritten after each frame, so a run that stops at any moment leaves a playable series.
"""

from __future__ import annotations

import base64
import contextlib
import io
import math
import os
import sys
import time as _time
import zlib
from pathlib import Path

import numpy as np

from ..atomic import atomic_write_bytes, atomic_write_text, sync_to_disk
from ..errors import IpcsimError, excerpt, one_line

__all__ = [
    "FRAMES_DIR",
    "SERIES_NAME",
    "FrameError",
    "FrameWriter",
    "frame_file_name",
    "frame_interval",
    "read_frame",
    "read_series",
]

FRAMES_DIR = "frames"
SERIES_NAME = "series.pvd"

# VTK cell type ids (vtkCellType.h)
_VTK_VERTEX, _VTK_LINE, _VTK_TRIANGLE, _VTK_TETRA = 1, 3, 5, 10

_VTK_TYPE_NAMES = {
    np.dtype(np.float32): "Float32",
    np.dtype(np.float64): "Float64",
    np.dtype(np.int8): "Int8",
    np.dtype(np.int16): "Int16",
    np.dtype(np.int32): "Int32",
    np.dtype(np.int64): "Int64",
    np.dtype(np.uint8): "UInt8",
    np.dtype(np.uint16): "UInt16",
    np.dtype(np.uint32): "UInt32",
    np.dtype(np.uint64): "UInt64",
}

_BYTE_ORDER = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
_BLOCK_SIZE = 1 << 15  # VTK's own default block size for compressed arrays


def _attribute(text: str) -> str:
    """``text`` as the value of a double-quoted XML attribute."""
    return (text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;"))


def frame_file_name(index: int) -> str:
    """``frame_000042.vtu`` for index 42."""
    return f"frame_{int(index):06d}.vtu"


COMPRESS_FROM = 1000  # vertices: below, zlib's set-up (20 µs an array) costs more than it saves


def frame_compression(n_vertices: int) -> int | None:
    """The zlib level of a run's frames: 1, or None (uncompressed) below
    ``COMPRESS_FROM`` vertices, where a frame is a few kilobytes either way."""
    return None if n_vertices < COMPRESS_FROM else 1


def frame_interval(dt: float, frame_dt: float = 0.01) -> int:
    """Steps between written frames: about one frame per ``frame_dt`` seconds of
    simulated time, never fewer than one frame per step."""
    if not dt > 0:
        raise ValueError(f"time step must be positive, got {dt!r}")
    return max(1, int(round(frame_dt / dt)))


def _encode_array(data: np.ndarray, level: int | None) -> str:
    """Base64 text of one DataArray in VTK's ``format="binary"`` layout with a UInt64
    header: uncompressed ``[nbytes] + data`` as one base64 run, or compressed
    ``[nblocks, blocksize, lastsize, csize...]`` then the compressed blocks."""
    raw = np.ascontiguousarray(data).tobytes()
    if level is None:
        header = np.array([len(raw)], dtype=np.uint64).tobytes()
        return base64.b64encode(header + raw).decode("ascii")
    blocks = [
        zlib.compress(raw[i : i + _BLOCK_SIZE], level) for i in range(0, len(raw), _BLOCK_SIZE)
    ]
    last = len(raw) - (len(blocks) - 1) * _BLOCK_SIZE if blocks else 0
    header = np.array(
        [len(blocks), _BLOCK_SIZE, last, *map(len, blocks)], dtype=np.uint64
    ).tobytes()
    # header and data are separate base64 runs, as VTK writes and reads them
    return (
        base64.b64encode(header).decode("ascii")
        + base64.b64encode(b"".join(blocks)).decode("ascii")
    )


def _data_array(name: str, data: np.ndarray, level: int | None, *, tuples: bool = False) -> str:
    type_name = _VTK_TYPE_NAMES[data.dtype]
    comps = f' NumberOfComponents="{data.shape[1]}"' if data.ndim == 2 else ""
    if tuples:  # VTK reads field-data arrays as empty without it
        comps += f' NumberOfTuples="{data.shape[0]}"'
    return (
        f'<DataArray type="{type_name}" Name="{_attribute(name)}"{comps} format="binary">'
        f"{_encode_array(data, level)}</DataArray>\n"
    )


def _as_point_array(name: str, values, n: int) -> np.ndarray:
    """Validate one point-data array and bring it to a dtype VTK stores."""
    a = np.asarray(values)
    if a.ndim not in (1, 2) or a.shape[0] != n:
        raise ValueError(f"point data {name!r} must have shape ({n},) or ({n}, k), got {a.shape}")
    if a.dtype == np.bool_:
        a = a.astype(np.uint8)  # VTK has no boolean arrays
    elif a.dtype.kind == "f" and a.dtype not in _VTK_TYPE_NAMES:
        a = a.astype(np.float64)
    elif a.dtype.kind not in "fiu":
        raise TypeError(f"point data {name!r} has unsupported dtype {a.dtype}")
    a = a.astype(a.dtype.newbyteorder("="), copy=False)
    return np.ascontiguousarray(a)


def _index_array(name: str, values, width: int | None, n: int) -> np.ndarray:
    a = np.asarray([] if values is None else values)
    if a.size == 0:  # `[]` arrives as float64; an empty set of cells has no dtype to check
        return np.zeros((0, width) if width else (0,), dtype=np.int64)
    if a.dtype.kind not in "iu":
        raise TypeError(f"{name} must be an integer array, got dtype {a.dtype}")
    expected = (a.shape[0], width) if width else (a.shape[0],)
    if a.shape != expected:
        want = f"(m, {width})" if width else "(m,)"
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if a.size and (a.min() < 0 or a.max() >= n):
        raise ValueError(f"{name} refers to vertices outside 0..{n - 1}")
    return np.ascontiguousarray(a, dtype=np.int64)


class FrameWriter:
    """Writes the frames of one run into ``<folder>/frames/``.

    Created once per run with the fixed mesh: ``body_id`` (n,) gives the number of
    vertices and which body each belongs to; ``tets`` (m, 4) become VTK tetra cells,
    ``triangles`` (k, 3) triangle cells (surfaces of kinematic ``.obj`` shapes),
    ``segments`` (s, 2) line cells and ``points`` (p,) vertex cells. Any of the cell
    arrays may be ``None`` or empty (with no cells at all, every vertex becomes a
    vertex cell). Cells appear in the file in that order.

    ``compression_level`` is the zlib level for per-frame arrays (``None`` writes them
    uncompressed); ``fsync`` forces every file to disk before it replaces the old one.
    Without it (the default: a run forces its output to disk at each checkpoint instead),
    files are still replaced atomically, and ``sync()`` forces those written since the
    last call to disk.
    """

    def __init__(
        self,
        folder: str | os.PathLike,
        tets=None,
        triangles=None,
        body_id=None,
        *,
        segments=None,
        points=None,
        compression_level: int | None = 1,
        fsync: bool = False,
    ):
        if body_id is None:
            raise ValueError("body_id (one entry per vertex) is required")
        body = np.asarray(body_id)
        if body.ndim != 1 or body.dtype.kind not in "iu":
            raise ValueError(f"body_id must be a 1-D integer array, got {body.dtype} {body.shape}")
        self.num_vertices = n = body.shape[0]
        if n == 0:
            raise ValueError("a frame needs at least one vertex")
        self.folder = Path(folder)
        self.frames_dir = self.folder / FRAMES_DIR
        self.series_path = self.frames_dir / SERIES_NAME
        self._frames_dir_name = os.fspath(self.frames_dir)
        if compression_level is not None and not 0 <= compression_level <= 9:
            raise ValueError(f"compression_level must be 0..9 or None, got {compression_level!r}")
        self._level = compression_level
        self.fsync = fsync

        blocks = [
            (_index_array("tets", tets, 4, n), _VTK_TETRA),
            (_index_array("triangles", triangles, 3, n), _VTK_TRIANGLE),
            (_index_array("segments", segments, 2, n), _VTK_LINE),
            (_index_array("points", points, None, n).reshape(-1, 1), _VTK_VERTEX),
        ]
        if not any(len(b) for b, _ in blocks):
            # no cells at all: show every vertex as a point (readers also choke on
            # empty cell arrays)
            blocks[3] = (np.arange(n, dtype=np.int64).reshape(-1, 1), _VTK_VERTEX)
        connectivity = np.concatenate([b.reshape(-1) for b, _ in blocks])
        sizes = np.concatenate([np.full(len(b), b.shape[1], dtype=np.int64) for b, _ in blocks])
        types = np.concatenate([np.full(len(b), t, dtype=np.uint8) for b, t in blocks])
        self.num_cells = len(types)
        # Fixed for the whole run: encode once, at the best compression, and reuse.
        level = None if compression_level is None else 6
        self._cells_xml = (
            "<Cells>\n"
            + _data_array("connectivity", connectivity, level)
            + _data_array("offsets", np.cumsum(sizes), level)
            + _data_array("types", types, level)
            + "</Cells>\n"
        )
        self._body_id = _as_point_array("body_id", body.astype(np.int64), n)
        self._body_xml = _data_array("body_id", self._body_id, compression_level)
        # index -> (time, file name, the frame's line of the series, formatted once)
        self._series: dict[int, tuple[float, str, str]] = {}
        self._unsynced: set[str] = set()  # written without fsync since the last sync()
        # The series is rewritten whole with every frame unless this many wall seconds
        # have not passed since it last was (a run sets it: 201 rewrites of a growing
        # file were a tenth of a tiny scene's run); flush() and sync() catch it up.
        self.series_interval = 0.0
        self._series_written = -math.inf  # time.monotonic() of the last rewrite
        self._series_behind = False
        self.frames_dir.mkdir(parents=True, exist_ok=True)

    @property
    def compression_level(self) -> int | None:
        # read-only: the cells were encoded for this setting at construction
        return self._level

    @property
    def frames(self) -> list[tuple[int, float, Path]]:
        """``(index, time, path)`` of every frame written so far, by index."""
        return [(i, t, self.frames_dir / f) for i, (t, f, _) in sorted(self._series.items())]

    def write(self, index: int, time: float, positions, velocity, fields=None,
              **point_data) -> Path:
        """Write frame ``index`` at simulated ``time`` [s] and update the series.

        ``positions`` and ``velocity`` are (n, 3); each keyword argument is one more
        point-data array of shape (n,) or (n, k) (booleans are stored as 0/1 UInt8);
        ``fields`` more field data, name to float array (a 2D scene's moving lines).
        Writing an index again replaces that frame. Returns the ``.vtu`` path.
        """
        index = int(index)
        if index < 0:
            raise ValueError(f"frame index must be >= 0, got {index}")
        time = float(time)
        n = self.num_vertices
        x = np.asarray(positions, dtype=np.float64)
        if x.shape != (n, 3):
            raise ValueError(f"positions must have shape ({n}, 3), got {x.shape}")
        arrays = {"velocity": np.asarray(velocity, dtype=np.float64)}
        if arrays["velocity"].shape != (n, 3):
            raise ValueError(f"velocity must have shape ({n}, 3), got {arrays['velocity'].shape}")
        for name, values in point_data.items():
            if name in ("body_id", "velocity"):
                raise ValueError(f"point data {name!r} is written by FrameWriter itself")
            arrays[name] = _as_point_array(name, values, n)

        level = self._level
        parts = [
            '<?xml version="1.0"?>\n',
            f'<VTKFile type="UnstructuredGrid" version="1.0" byte_order="{_BYTE_ORDER}" '
            'header_type="UInt64"'
            + (' compressor="vtkZLibDataCompressor"' if level is not None else "")
            + ">\n<UnstructuredGrid>\n",
            # TimeValue lets ParaView show the time even when one .vtu is opened alone
            "<FieldData>\n",
            _data_array("TimeValue", np.array([time]), level, tuples=True),
            *(_data_array(name, np.asarray(a, dtype=np.float64).reshape(-1), level,
                          tuples=True) for name, a in (fields or {}).items()),
            "</FieldData>\n",
            f'<Piece NumberOfPoints="{n}" NumberOfCells="{self.num_cells}">\n',
            "<PointData>\n",
            self._body_xml,
            *(_data_array(name, a, level) for name, a in arrays.items()),
            "</PointData>\n<Points>\n",
            _data_array("Points", x, level),
            "</Points>\n",
            self._cells_xml,
            "</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
        ]
        name = frame_file_name(index)
        path = os.path.join(self._frames_dir_name, name)  # a string: Path parsing costs
        atomic_write_bytes(path, "".join(parts).encode("ascii"), fsync=self.fsync)
        self._unsynced.add(path)
        self._add_to_series(index, time, name)
        if _time.monotonic() - self._series_written >= self.series_interval:
            self._write_series()
        else:
            self._series_behind = True
        return Path(path)

    def flush(self) -> None:
        """Bring the series up to date with every frame written."""
        if self._series_behind:
            self._write_series()

    def sync(self) -> None:
        """Bring the series up to date and force the frames and the series written since
        the last call to disk."""
        self.flush()
        sync_to_disk(sorted(self._unsynced))
        self._unsynced.clear()

    def resume(self, last_index: int, time_of) -> None:
        """Continue a run whose frames are already in the folder: frames up to
        ``last_index`` join the series (``time_of(index)`` gives their time), later ones
        are removed (the steps they show are computed again)."""
        for path in sorted(self.frames_dir.glob("frame_*.vtu")):
            try:
                index = int(path.stem.split("_", 1)[1])
            except ValueError:
                continue
            if index > last_index:
                path.unlink()
            else:
                self._add_to_series(index, float(time_of(index)), path.name)
        self._write_series()

    def _add_to_series(self, index: int, time: float, name: str) -> None:
        # repr keeps the exact double; ParaView and pyvista parse it as a float
        line = f'    <DataSet timestep="{time!r}" part="0" file="{_attribute(name)}"/>\n'
        self._series[index] = (time, name, line)

    def _write_series(self) -> None:
        lines = [
            '<?xml version="1.0"?>\n',
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n',
            "  <Collection>\n",
            *(line for _, (_, _, line) in sorted(self._series.items())),
            "  </Collection>\n</VTKFile>\n",
        ]
        atomic_write_text(self.series_path, "".join(lines), fsync=self.fsync)
        self._unsynced.add(os.fspath(self.series_path))
        self._series_written = _time.monotonic()
        self._series_behind = False


class FrameError(IpcsimError):
    """A frame or series file that cannot be read (damaged, truncated, not VTK)."""


def read_series(pvd_path: str | os.PathLike) -> list[tuple[float, Path]]:
    """``(time, vtu path)`` for every data set of a ``.pvd`` file, in file order.

    Paths are resolved relative to the ``.pvd`` file's folder. A file that is not a
    readable series is a :class:`FrameError`."""
    from xml.etree import ElementTree  # reading runs back only: not on a run's start

    from ..files import read_regular_file

    pvd_path = Path(pvd_path)
    try:
        root = ElementTree.fromstring(read_regular_file(pvd_path))
        series = []
        for ds in root.iter("DataSet"):
            name = ds.get("file")
            if not name:
                raise ValueError("a DataSet without a file")
            series.append((float(ds.get("timestep", "0")), pvd_path.parent / name))
    except (OSError, ValueError, ElementTree.ParseError) as exc:
        raise FrameError(f"{pvd_path}: not a readable series "
                         f"({one_line(exc, 120) or type(exc).__name__})") from None
    return series


def read_frame(path: str | os.PathLike):
    """One ``.vtu`` frame as a ``meshio.Mesh``. meshio's per-format reader is called
    directly: ``meshio.read`` prints and calls ``sys.exit`` on a damaged file. Every
    failure is a :class:`FrameError` naming the file."""
    import meshio

    path = Path(path)
    if not path.is_file():
        raise FrameError(f"{path}: frame not found" if not path.exists()
                         else f"{path}: not a regular file")
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            mesh = meshio.vtu.read(str(path))
    except (Exception, SystemExit) as exc:  # ReadError, ValueError, zlib.error, ...
        why = one_line(exc, 120) or "damaged or truncated"
        raise FrameError(f"{path}: cannot read frame ({why})") from None
    n = len(mesh.points)
    if np.ndim(mesh.points) != 2 or np.shape(mesh.points)[1] != 3:
        raise FrameError(f"{path}: a frame needs 3-D points, got shape "
                         f"{np.shape(mesh.points)}")
    for block in mesh.cells:
        data = np.asarray(block.data)
        if data.size and (data.min() < 0 or data.max() >= n):
            raise FrameError(f"{path}: its {block.type} cells name vertices outside "
                             f"0..{n - 1}")
    for name, values in mesh.point_data.items():
        if len(values) != n:
            raise FrameError(f"{path}: point data {excerpt(name)} has {len(values)} "
                             f"entries for {n} vertices")
    return mesh
