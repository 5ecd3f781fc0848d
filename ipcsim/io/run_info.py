"""``run.json``: what ran, where, with which software, and how long it took.

:func:`write_run_info` fills in the environment (versions, platform, command line)
itself and merges the caller's run facts over it; every key of :data:`RUN_KEYS` is
always present (``null`` when the caller did not give it), so readers need no guessing.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from ..atomic import atomic_write_text

__all__ = ["RUN_INFO_NAME", "RUN_KEYS", "environment_info", "now_iso", "peak_memory_mb",
           "write_run_info"]

RUN_INFO_NAME = "run.json"

# Facts only the caller knows; written as null until it supplies them.
RUN_KEYS: tuple[str, ...] = (
    "scene",
    "output",
    "status",
    "started",
    "finished",
    "wall_s",
    "peak_memory_mb",
    "steps_planned",
    "steps_done",
    "newton_iterations",
    "steps_hitting_iteration_cap",
    "steps_not_converged",
    "inputs_sha256",
    "modelled_terms",
    "linear_solver",
)


def peak_memory_mb() -> float | None:
    """This process's peak resident memory in MB: VmHWM of /proc/self/status, the high
    water mark of its own address space (``ru_maxrss`` would also count the parent's,
    which a forked child holds until it execs); ``ru_maxrss`` where /proc is missing."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0  # kB
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource

        scale = 1024.0 * 1024.0 if sys.platform == "darwin" else 1024.0  # bytes / kB
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / scale
    except (ImportError, OSError):
        return None


def now_iso() -> str:
    """The current local time as ISO 8601 with its UTC offset, to the second."""
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def _versions(*dists: str) -> dict[str, str | None]:
    """The installed version of each distribution, from the name of its
    ``<name>-<version>.dist-info`` folder on the import path (how installers name it,
    PEP 427) without importing the package (numba takes seconds) or importlib.metadata
    (25 ms with the email parser it loads, a tenth of a tiny scene's start); each folder
    of the path is listed once, the first found counts."""
    prefixes = {dist: dist.replace("-", "_").lower() + "-" for dist in dists}
    found: dict[str, str | None] = dict.fromkeys(dists)
    for entry in sys.path:
        try:
            names = [n for n in os.listdir(entry or ".") if n.endswith(".dist-info")]
        except OSError:
            continue
        for dist, prefix in prefixes.items():
            if found[dist] is None:
                found[dist] = next((n[len(prefix):-len(".dist-info")] for n in names
                                    if n.lower().startswith(prefix)), None)
        if None not in found.values():
            break
    return found


def environment_info() -> dict:
    """Versions of ipcsim and its numerical stack, the platform and the command line."""
    from .. import __version__
    from ..compiler.aot import machine  # here: a run has it loaded, other readers need not

    return {
        "ipcsim_version": __version__,
        "python_version": sys.version.split()[0],  # platform.python_version()'s
        "numpy_version": np.__version__,
        **{f"{dist}_version": version
           for dist, version in _versions("scipy", "numba", "meshio").items()},
        "platform": _platform(),
        "machine": machine(),
        "processor_count": os.cpu_count(),
        "command": list(sys.argv),
    }


def _platform() -> str:
    """``platform.platform()``'s system-release-machine[-with-libc], from ``uname`` and
    the C library's own answer: ``platform.platform()`` itself runs ``uname -p`` in a
    subprocess and scans the interpreter's binary for the libc version (10–15 ms, a
    twentieth of a tiny scene's whole run)."""
    from ..compiler.aot import uname

    system, _, release, _, machine = uname()
    name = f"{system}-{release}-{machine}"
    try:
        libc = os.confstr("CS_GNU_LIBC_VERSION")  # "glibc 2.36"
    except (AttributeError, ValueError, OSError):
        libc = None
    return f"{name}-with-{libc.replace(' ', '')}" if libc else name


def _plain(value):
    """The run's facts as plain JSON values; non-finite floats become null because
    strict JSON has no NaN or infinity."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (set, frozenset)):
        return [_plain(v) for v in sorted(value, key=str)]  # a stable order for diffs
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (str, int, bool)):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, (_dt.datetime, _dt.date)):
        return value.isoformat()
    raise TypeError(f"run.json cannot hold a {type(value).__name__}")


def write_run_info(folder: str | os.PathLike, info: dict) -> Path:
    """Write ``<folder>/run.json`` atomically and return its path.

    Contents: :func:`environment_info`, then every key of :data:`RUN_KEYS` (``null`` by
    default), then ``info`` on top (its keys win, extra keys are kept). Call it again to
    update the file, e.g. once at the start with ``status="running"`` and once at the end.
    """
    data = environment_info()
    data.update(dict.fromkeys(RUN_KEYS))
    data.update(info)
    text = json.dumps(_plain(data), indent=2, allow_nan=False) + "\n"
    return atomic_write_text(Path(folder) / RUN_INFO_NAME, text)
