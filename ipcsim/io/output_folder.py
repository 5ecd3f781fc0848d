"""The output folder of a run: where it goes by default, checking it before anything is
written (:func:`resolve_output_folder`), holding it for one process (:func:`hold_folder`)
and preparing it (:func:`prepare_output_folder`); and the folder of a study
(:func:`resolve_study_folder`, :func:`clear_study_folder`).

A run never mixes its files with an earlier run's or with the user's own: the folder is
made absolute and normalised first, so ``missing/../old_run`` is recognised as the
existing ``old_run``; an existing, non-empty folder is refused unless the user asks to
overwrite (or resume); the current directory and the scene's own folder are refused for
a new run; and overwriting removes only the files ipcsim itself writes there, never
anything else the user keeps in that folder, and only once the new run has been built.

One process at a time writes a folder: a run (new, overwriting or resumed) and a study
hold theirs with an exclusive ``flock`` on ``.ipcsim-lock`` inside it for as long as they
write, and a second writer is refused, naming the folder and the holder's pid (which the
holder writes into the file). The kernel releases the lock when its holder ends, killed
or not, so no stale lock is ever left. The holder removes the file as it lets go (a
process that opened it meanwhile sees the name no longer leads to its file and takes
the new one); a killed holder's file stays, unlocked, and is no content of the folder
(an overwrite keeps it; a folder holding only it counts as empty).
"""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

try:
    import fcntl
except ImportError:  # not a POSIX system: folders are not locked
    fcntl = None

from ..atomic import is_temporary_name
from ..errors import IpcsimError, excerpt
from .checkpoint import CHECKPOINT_NAME
from .csv_log import NewtonLog, StepLog
from .run_info import RUN_INFO_NAME
from .vtk import FRAMES_DIR, SERIES_NAME

__all__ = [
    "LOCK_NAME",
    "FolderLock",
    "OUTPUT_ROOT",
    "OWN_FILES",
    "OutputFolderError",
    "default_output_folder",
    "holds_anything",
    "hold_folder",
    "prepare_output_folder",
    "resolve_output_folder",
    "STUDY_CHART",
    "STUDY_COLUMNS",
    "STUDY_MARK",
    "STUDY_RUNS",
    "STUDY_TABLE",
    "clear_study_folder",
    "is_study_folder",
    "mark_study_folder",
    "resolve_study_folder",
]

OUTPUT_ROOT = "output"
LOCK_NAME = ".ipcsim-lock"
STUDY_TABLE = "study.csv"
STUDY_CHART = "study.png"
STUDY_RUNS = "runs"
RUN_DIGEST_CHARS = 16  # a study's run folder: runs/<the first characters of its digest>
STUDY_MARK = ".ipcsim-study"  # the name of the study file that writes the folder
STUDY_COLUMNS = ("run", "status", "error")  # study.csv's first columns, always

# Top-level entries a run writes; with overwrite, exactly these are removed.
OWN_FILES: tuple[str, ...] = (
    FRAMES_DIR,
    StepLog.FILE_NAME,
    NewtonLog.FILE_NAME,
    RUN_INFO_NAME,
    "scene.toml",
    CHECKPOINT_NAME,
)


class OutputFolderError(IpcsimError):
    """The output folder cannot be used (exists with content, or is not a folder)."""


def default_output_folder(scene_path: str | os.PathLike, append_str: str = "") -> Path:
    """``output/<scene-stem>`` (``output/<scene-stem>_<appendStr>`` when the scene says
    ``appendStr``), relative to the current directory."""
    stem = Path(scene_path).stem
    if stem in ("", ".", "..") or stem.strip(".") == "":
        raise OutputFolderError(f"cannot name an output folder after the scene file "
                                f"'{excerpt(Path(scene_path).name)}'; pass -o DIR")
    return Path(OUTPUT_ROOT) / (f"{stem}_{append_str}" if append_str else stem)


def _same_or_inside(folder: Path, other: Path) -> bool:
    """True when ``other`` is ``folder`` or lies inside it (lexically or through links)."""
    pairs = [(folder, other), (Path(os.path.realpath(folder)), Path(os.path.realpath(other)))]
    return any(b == a or a in b.parents for a, b in pairs)


def _absolute_folder(requested, what: str) -> Path:
    """``requested`` absolute and normalised; a file in the way is refused."""
    path = Path(os.path.normpath(os.path.abspath(requested)))
    if path.exists() and not path.is_dir():
        raise OutputFolderError(f"{what} {path} exists and is not a folder")
    return path


def _refuse_shared_folder(path: Path, places, what: str, writes: str) -> None:
    """Refuse ``path`` when it is one of ``places`` ((name, folder) pairs) or lies above
    one: the output would mix with the user's own files."""
    for name, where in places:
        if _same_or_inside(path, Path(where)):
            here = "is" if path == where else "contains"
            raise OutputFolderError(f"{what} {path} {here} {name}; {writes} there: pass -o "
                                    "with a folder of its own")


def _check_creatable(path: Path, what: str) -> None:
    existing = next(p for p in (path, *path.parents) if p.exists())
    if not existing.is_dir():
        raise OutputFolderError(f"cannot create {what} {path}: {existing} is not a folder")
    _check_writable(existing)


def resolve_output_folder(requested, scene_path, *, mode: str) -> Path:
    """The output folder a run will write, absolute and normalised (``missing/../run`` is
    ``run``), checked before anything is written; ``mode`` is ``"new"``, ``"overwrite"``
    or ``"resume"``.

    Refused with :class:`OutputFolderError`: a file in the way; for a new or overwriting
    run, the current directory, the scene's own folder or a folder above either (a run
    there would mix its files with the user's), and a study's folder; for a new run, an
    existing folder that is not empty (pass --overwrite or --resume); for a resume, a
    folder that does not exist; a folder that cannot be created or written.
    """
    path = _absolute_folder(requested, "output folder")
    if mode == "resume":
        if not path.is_dir():
            raise OutputFolderError(f"{path}: no such output folder to resume")
        _check_writable(path)
        return path
    _refuse_shared_folder(path, (("the current directory", Path.cwd()),
                                 ("the scene's folder", Path(os.path.abspath(scene_path)).parent)),
                          "output folder", "a run writes frames/, steps.csv and more")
    if holds_anything(path):
        if mode != "overwrite":
            raise OutputFolderError(f"output folder {path} exists; pass --overwrite "
                                    "(or --resume)")
        if is_study_folder(path):
            raise OutputFolderError(f"output folder {path} is a study's folder (study.csv, "
                                    "runs/); a run needs a folder of its own: pass -o "
                                    "another folder")
    _check_usable(path, "output folder")
    return path


def _check_usable(path: Path, what: str) -> None:
    """A folder that holds something must be writable; one that does not, creatable."""
    if holds_anything(path):
        _check_writable(path)
    else:
        _check_creatable(path, what)


def _check_writable(folder: Path) -> None:
    for f in (folder, folder / FRAMES_DIR):
        if f.is_dir() and not os.access(f, os.W_OK | os.X_OK):
            raise OutputFolderError(f"cannot write in {f} (permission denied)")


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink()


def _clear_frames(frames: Path) -> None:
    # Only frame files, the series and leftover temporaries: the folder may hold a
    # user's own files (a ParaView state, say), which stay.
    if frames.is_symlink() or not frames.is_dir():
        _remove(frames)
        return
    for entry in frames.iterdir():
        name = entry.name
        ours = (
            (name.startswith("frame_") and name.endswith(".vtu"))
            or name == SERIES_NAME
            or is_temporary_name(name)
        )
        if ours and not entry.is_dir():
            entry.unlink()


def prepare_output_folder(path: str | os.PathLike, overwrite: bool) -> Path:
    """Create ``path`` and ``path/frames`` for a new run and return ``path``.

    An existing folder that is not empty is refused with :class:`OutputFolderError`
    unless ``overwrite`` is true; then ipcsim's own files (``frames/`` contents,
    ``steps.csv``, ``newton.csv``, ``run.json``, ``scene.toml``, ``checkpoint.npz``, leftover temporary
    files) are removed and everything else is left alone.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputFolderError(f"output folder {path} exists and is not a folder")
    try:
        if holds_anything(path):
            if not overwrite:
                raise OutputFolderError(f"output folder {path} exists; pass --overwrite")
            for entry in path.iterdir():
                if entry.name == FRAMES_DIR:
                    _clear_frames(entry)
                elif entry.name in OWN_FILES or is_temporary_name(entry.name):
                    _remove(entry)
        (path / FRAMES_DIR).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFolderError(f"cannot prepare output folder {path}: "
                                f"{exc.strerror or exc}") from None
    return path


def holds_anything(folder: Path) -> bool:
    """True when ``folder`` is a folder with some entry besides its lock file."""
    folder = Path(folder)
    return folder.is_dir() and any(e.name != LOCK_NAME for e in folder.iterdir())


class FolderLock:
    """This process's exclusive hold on a folder (:func:`hold_folder`); ``release`` (or
    the end of a ``with`` block, or of the process) lets it go."""

    def __init__(self, folder: Path, fd: int | None):
        self.folder, self._fd = folder, fd

    def release(self) -> None:
        """Remove the lock file, then let the lock go: a process that opened the file
        meanwhile finds, once it holds the lock, that the name no longer leads to it,
        and tries again (:func:`hold_folder`)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.folder / LOCK_NAME)
        except OSError:
            pass  # gone with its folder (a study's --overwrite), or a read-only folder
        os.close(self._fd)  # closing the file releases the lock
        self._fd = None

    def __enter__(self) -> "FolderLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def hold_folder(folder, what: str = "output folder") -> FolderLock:
    """Create ``folder`` if it does not exist and hold it for this process: an
    :class:`OutputFolderError` (exit status 2) when another process holds it, naming the
    folder and that process. A file system without locks (some network mounts) is used
    unlocked."""
    folder = Path(folder)
    path = folder / LOCK_NAME
    while True:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as exc:
            raise OutputFolderError(f"cannot use {what} {folder}: "
                                    f"{exc.strerror or exc}") from None
        if fcntl is None:
            return FolderLock(folder, fd)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return FolderLock(folder, fd)  # no locks here (ENOLCK): go on unlocked
            holder = _holder(fd)
            os.close(fd)
            raise OutputFolderError(f"{what} {folder} is in use by another ipcsim process"
                                    f"{holder}; wait for it to end or stop it, or choose "
                                    "another folder") from None
        if _names(path, fd):
            break
        os.close(fd)  # its holder removed it as we opened it: take the new one
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return FolderLock(folder, fd)


def _names(path: Path, fd: int) -> bool:
    """True while ``path`` still leads to the open file ``fd``."""
    try:
        here, held = os.stat(path), os.fstat(fd)
    except OSError:
        return False
    return (here.st_dev, here.st_ino) == (held.st_dev, held.st_ino)


def _holder(fd: int) -> str:
    """" (pid N)" of the process that holds a lock file, from what it wrote there."""
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    except OSError:
        return ""
    return f" (pid {text})" if text.isdigit() else ""


def _is_run_folder(path: Path) -> bool:
    name = path.name
    return (len(name) == RUN_DIGEST_CHARS and all(c in "0123456789abcdef" for c in name)
            and path.is_dir() and not path.is_symlink())


def holds_a_run(folder: Path) -> bool:
    """True when ``folder`` holds some file or folder that a run writes."""
    return any((Path(folder) / name).exists() for name in OWN_FILES)


def _is_study_table(path: Path) -> bool:
    """True when ``path`` is a study.csv that a study wrote (its first columns)."""
    from ..files import read_regular_file

    try:
        head = read_regular_file(path, 256).decode("utf-8", "replace")
    except OSError:
        return False
    return head.split("\n", 1)[0].split(",")[:3] == list(STUDY_COLUMNS)


def is_study_folder(folder) -> bool:
    """True for a folder that a study wrote: it holds ``runs/`` or a study's study.csv,
    no other study.csv and nothing a run writes."""
    folder = Path(folder)
    table = folder / STUDY_TABLE
    ours = table.exists() and _is_study_table(table)
    if table.exists() and not ours or holds_a_run(folder):
        return False
    return ours or (folder / STUDY_RUNS).is_dir() or (folder / STUDY_MARK).is_file()


def _study_of(folder: Path) -> str | None:
    """The name of the study file that wrote ``folder`` (None where it did not say)."""
    from ..files import read_regular_file

    try:
        return read_regular_file(folder / STUDY_MARK, 4096).decode("utf-8").strip() or None
    except (OSError, UnicodeDecodeError):
        return None


def mark_study_folder(folder: Path, study_name: str) -> None:
    """Note in ``folder`` which study file writes it (:func:`resolve_study_folder`)."""
    from ..atomic import atomic_write_text

    if _study_of(folder) != study_name:
        atomic_write_text(Path(folder) / STUDY_MARK, study_name + "\n")


def resolve_study_folder(requested, shared, *, overwrite: bool, study_name: str) -> Path:
    """The folder a study (of the file named ``study_name``) will write, absolute and
    normalised, checked before anything is written: the study's own folder (its runs are
    continued, or replaced with ``overwrite``), a new or empty one, or, with
    ``overwrite``, another study's folder or a folder whose study.csv, study.png and
    runs/ may be replaced. Refused with :class:`OutputFolderError`: a file in the way, a
    run's folder, another study's folder and any other folder that holds something
    (without ``overwrite``), and ``shared`` ((name, folder) pairs: the current
    directory, the study file's and the scene's folders) or a folder above one, unless
    it is a study's folder."""
    path = _absolute_folder(requested, "study folder")
    if is_study_folder(path):
        other = _study_of(path)
        if other not in (None, study_name) and not overwrite:
            raise OutputFolderError(f"study folder {path} holds the study of "
                                    f"{excerpt(other, 80)}, not of {excerpt(study_name, 80)}; "
                                    "pass --overwrite to replace it, or -o another folder")
        _check_writable(path)
        return path
    if holds_a_run(path):
        raise OutputFolderError(f"study folder {path} holds an ipcsim run (frames/, "
                                "steps.csv); a study needs a folder of its own: pass -o "
                                "another folder")
    _refuse_shared_folder(path, shared, "study folder",
                          "a study writes study.csv, study.png and runs/")
    if holds_anything(path):
        if not overwrite:
            raise OutputFolderError(f"study folder {path} exists and holds no study; pass "
                                    "--overwrite to write the study there (its study.csv, "
                                    "study.png and runs/ are replaced, nothing else), or "
                                    "-o another folder")
    _check_usable(path, "study folder")
    return path


def clear_study_folder(folder: Path) -> None:
    """Remove what a study writes in ``folder`` (study.csv, study.png, the run folders in
    runs/, each held while it goes, and leftover temporaries) and nothing else."""
    folder = Path(folder)
    runs = folder / STUDY_RUNS
    try:
        if runs.is_dir() and not runs.is_symlink():
            for run in runs.iterdir():
                if _is_run_folder(run):
                    with hold_folder(run, "run folder"):
                        shutil.rmtree(run)
            if not any(runs.iterdir()):
                runs.rmdir()
        for entry in folder.iterdir():
            if entry.name in (STUDY_TABLE, STUDY_CHART, STUDY_MARK) \
                    or is_temporary_name(entry.name):
                _remove(entry)
    except OSError as exc:
        raise OutputFolderError(f"cannot clear study folder {folder}: "
                                f"{exc.strerror or exc}") from None
